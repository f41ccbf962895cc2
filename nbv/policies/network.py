"""A trained PCNBV / PCNBV-sph checkpoint as a view-selection policy."""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from nbv.geometry.clouds import farthest_points
from nbv.policies.episode import EpisodeState
from nbv.policies.inputs import cloud_or_origin, record_time, safe_signature
from nbv.policies.lockstep import NetworkRequest

#: Samples a batched forward pass holds at most (larger batches run in chunks): 32 samples of
#: 512 points keep the widest activation, (32, 512, 1024) float32, at 64 MB.
MAX_BATCH = 32
#: Points a chunk holds at most. A wide activation of more than about 2,048 points leaves the
#: cache: on a 2-core AMD EPYC (2026-12-03, one thread) a 512-point PCNBV forward took 37-39 ms
#: a sample in batches of 1 to 8 and 48 ms in a batch of 32 (float32; bfloat16: 25 ms at 4,
#: 31 ms at 32), while PCNBV-sph's 64-point forwards gain up to batches of 32.
MAX_POINTS = 2048


def chunk_size(points: int) -> int:
    """Samples of ``points`` points a forward pass takes at once: as many as :data:`MAX_POINTS`
    allows, at least 1 and at most :data:`MAX_BATCH`."""
    return max(1, min(MAX_BATCH, MAX_POINTS // max(points, 1)))


@dataclass
class NetworkPolicy:
    """A PCNBV network: the accumulated cloud (farthest point sampled to ``n_points``) or its
    spherical signature (``input == "signature"``, degree ``lmax``) and the view state in, the
    best unvisited view of its predicted gains out.

    ``precision`` is the arithmetic of the forward pass (:data:`nbv.models.precision.PRECISIONS`;
    ``"auto"`` is bfloat16 autocast where the CPU runs it natively). ``timings`` collects seconds
    per decision: ``sampling`` (or ``signature``) and ``network``.

    ``selected_on`` names the models whose episodes chose the checkpoint (the training's
    validation models, or for a checkpoint of an older version, chosen on its held-out category,
    ``category:<name>``): an evaluation must not score them.
    """

    # nbv.models.pcnbv.PCNBV, kept untyped so that importing this module needs no torch
    model: object
    input: str = "points"
    n_points: int = 512
    lmax: int = 3
    precision: str = "auto"
    timings: dict[str, list[float]] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    counts: dict[str, int] = field(default_factory=dict)
    last_gains: list[float] = field(default_factory=list)
    selected_on: tuple[str, ...] = ()

    @classmethod
    def from_checkpoint(
        cls, path: str | Path, n_views: int | None = None, precision: str | None = None
    ) -> NetworkPolicy:
        """Load a training checkpoint (``best.pt``); its ``extra`` says the input kind, the
        number of points and (unless ``precision`` is given) the precision it was trained with:
        ``fp32``, or ``bf16``, which runs as ``auto`` (bfloat16 where the CPU runs it natively,
        float32 elsewhere).

        Raises:
            nbv.models.checkpoints.CheckpointError: the file is missing or unusable (the message
                names it).
        """
        from nbv.models.checkpoints import load_checkpoint
        from nbv.models.inference import for_inference

        net, extra = load_checkpoint(path, n_views=n_views)
        # A network trained in bfloat16 runs in it only where the CPU has it natively: emulated
        # bfloat16 is tens of times slower than float32 (0.9 s against 0.14 s a forward on an
        # AVX2 core), and the two agree to bfloat16's three digits.
        trained = str(extra.get("precision", "fp32"))
        precision = precision or ("auto" if trained == "bf16" else trained)
        if "selection_keys" in extra:
            selected_on = tuple(extra["selection_keys"])
        else:  # older training chose best.pt on its held-out category
            selected_on = (f"category:{extra['held_out']}",) if extra.get("held_out") else ()
        return cls(
            for_inference(net, precision),
            input=str(extra.get("input", "points")),
            n_points=int(extra.get("eval_points", 1024)),
            lmax=int(extra.get("lmax", 3)),
            precision=precision,
            selected_on=selected_on,
        )

    def fresh(self) -> NetworkPolicy:
        """The same network with empty ``timings`` and ``notes`` (one per episode)."""
        return NetworkPolicy(
            self.model, self.input, self.n_points, self.lmax, self.precision,
            selected_on=self.selected_on,
        )  # fmt: skip

    def features(self, cloud: np.ndarray) -> np.ndarray:
        """The network input for a cloud: (n_points, 3) or the (4 (lmax+1)^2, 3) signature."""
        cloud = cloud_or_origin(cloud)
        if self.input == "signature":
            return safe_signature(cloud, self.lmax, self.notes)
        return farthest_points(cloud, self.n_points)

    def predict(self, cloud: np.ndarray, view_state: np.ndarray) -> np.ndarray:
        """(V,) float32 predicted gain of every view (visited ones included) for ``cloud``
        ((N, 3) float accumulated cloud, world units) and ``view_state`` ((V,) bool, the state
        the network is shown). The same as :meth:`predict_many` of one episode."""
        return self.predict_many([cloud], [view_state])[0]

    def predict_many(
        self,
        clouds: Sequence[np.ndarray],
        view_states: Sequence[np.ndarray],
        episodes: Sequence[NetworkPolicy] | None = None,
    ) -> np.ndarray:
        """(K, V) float32 predicted gains of K episodes in one batched forward pass.

        Every episode's input is computed alone, as :meth:`predict` computes it (farthest point
        sampling is deterministic, and a cloud of fewer points is repeated to ``n_points``; a
        signature has ``4 (lmax+1)^2`` points): every sample holds the same number of points, so
        nothing is padded and each row is the network's function of its own episode only.

        Args:
            clouds: K (N_k, 3) float accumulated clouds, world units (any N_k, 0 included).
            view_states: K (V,) bool states the network is shown.
            episodes: the K episodes' own policies (each a :meth:`fresh` copy of this one):
                each gets its own ``sampling`` (or ``signature``) seconds and notes, and an equal
                share of the batched forward's seconds as its ``network`` time; None = all of
                it on this policy.

        Returns:
            (K, V) float32; row k equals ``predict(clouds[k], view_states[k])`` up to the last
            bits of float32 sums (a batched matrix product may add in another order).

        Raises:
            ValueError: the lengths differ, or an episode's policy runs another network or input.
        """
        k = len(clouds)
        episodes = self._episodes(episodes, k)
        if len(view_states) != k:
            raise ValueError(
                f"{k} clouds but {len(view_states)} view states: one of each an episode"
            )
        stage = "signature" if self.input == "signature" else "sampling"
        inputs = []
        for episode, cloud in zip(episodes, clouds, strict=True):
            t0 = time.perf_counter()
            inputs.append(episode.features(cloud))
            record_time(episode.timings, stage, time.perf_counter() - t0)
        t1 = time.perf_counter()
        scores = self.forward(inputs, view_states)
        share = (time.perf_counter() - t1) / max(k, 1)
        for episode in episodes:
            record_time(episode.timings, "network", share)
        return scores

    def forward(
        self, inputs: Sequence[np.ndarray], view_states: Sequence[np.ndarray]
    ) -> np.ndarray:
        """(K, V) float32 network output for K inputs of :meth:`features` (each (P, 3), the same
        P) and K (V,) view states: one forward pass, in chunks of :func:`chunk_size` samples."""
        import torch

        from nbv.models.precision import autocast, flush_denormals

        n_views = self.model.config.n_views
        if not len(inputs):
            return np.zeros((0, n_views), dtype=np.float32)
        device = next(self.model.parameters()).device
        x_all = np.ascontiguousarray(np.stack(inputs), dtype=np.float32)
        s_all = np.stack([np.asarray(s, dtype=np.float32) for s in view_states])
        out = []
        with torch.inference_mode(), flush_denormals(), autocast(self.precision, device):
            step = chunk_size(x_all.shape[1])
            for i in range(0, len(x_all), step):
                x = torch.from_numpy(x_all[i : i + step]).to(device)
                s = torch.from_numpy(s_all[i : i + step]).to(device)
                out.append(self.model(x, s).float().cpu().numpy())
        return np.concatenate(out)

    def _episodes(self, episodes: Sequence[NetworkPolicy] | None, k: int) -> list[NetworkPolicy]:
        """The episodes' policies, checked to run this network on the same input."""
        if episodes is None:
            return [self] * k
        episodes = list(episodes)
        if len(episodes) != k:
            raise ValueError(f"{k} episodes' inputs but {len(episodes)} episode policies")
        mine = (self.input, self.n_points, self.lmax, self.precision)
        for i, episode in enumerate(episodes):
            theirs = (episode.input, episode.n_points, episode.lmax, episode.precision)
            if episode.model is not self.model or theirs != mine:
                raise ValueError(
                    f"episode {i}'s policy runs another network or input "
                    f"(input, n_points, lmax, precision = {theirs}, this one {mine}): batch only "
                    "the fresh() copies of one policy"
                )
        return episodes

    def decide(
        self, cloud: np.ndarray, view_state: np.ndarray, visited: np.ndarray | None = None
    ) -> int:
        """The best view of the network's prediction for ``cloud`` and ``view_state``.

        Args:
            cloud: (N, 3) float accumulated cloud, world units.
            view_state: (V,) bool, the state the network is shown.
            visited: (V,) bool, the views that may not be chosen; default ``view_state``. (The
                disturbance checks show the network another state than the true one.)

        Returns:
            The index of the highest-scoring view not in ``visited``, ties to the lowest.
        """
        return self.decide_many([cloud], [view_state], None if visited is None else [visited])[0]

    def decide_many(
        self,
        clouds: Sequence[np.ndarray],
        view_states: Sequence[np.ndarray],
        visited: Sequence[np.ndarray] | None = None,
        episodes: Sequence[NetworkPolicy] | None = None,
    ) -> list[int]:
        """:meth:`decide` for K episodes with one batched forward (:meth:`predict_many`):
        ``clouds`` K (N_k, 3), ``view_states`` K (V,) bool shown states, ``visited`` K (V,) bool
        views each may not choose (None = its shown state), ``episodes`` the K episodes' own
        policies for their timings and notes. Returns the K chosen views."""
        import torch

        from nbv.models.inference import masked_argmax  # refuses NaN scores and a full state

        scores = self.predict_many(clouds, view_states, episodes)
        masks = view_states if visited is None else visited
        if len(masks) != len(scores):
            raise ValueError(f"{len(scores)} episodes but {len(masks)} visited states")
        if not len(scores):
            return []
        mask = torch.from_numpy(np.stack([np.asarray(m, bool) for m in masks]))
        return [int(v) for v in masked_argmax(torch.from_numpy(scores), mask)]

    def choose_many(
        self, states: Sequence[EpisodeState], episodes: Sequence[NetworkPolicy] | None = None
    ) -> list[int]:
        """The next view of K episodes (what calling each episode's policy on its state would
        choose), from one batched forward pass.

        Args:
            states: the K episodes' states (any models, viewspaces of V views, numbers of
                visited views).
            episodes: the K episodes' own policies (:meth:`fresh` copies of this one), which
                record their timings and notes as the Policy protocol wants; None = this one.

        Returns:
            K unvisited view indices, ``episodes[k](states[k])`` for every k.
        """
        clouds = [state.cloud() for state in states]
        return self.decide_many(clouds, [state.view_state for state in states], None, episodes)

    def view_scores_many(
        self, states: Sequence[EpisodeState], episodes: Sequence[NetworkPolicy] | None = None
    ) -> np.ndarray:
        """(K, V) :meth:`view_scores` of K states, one batched forward pass."""
        return self.predict_many([s.cloud() for s in states], [s.view_state for s in states],
                                 episodes)  # fmt: skip

    def view_scores(self, state: EpisodeState) -> np.ndarray:
        """(V,) the scores this policy picks by in ``state`` (see :meth:`predict`)."""
        return self.predict(state.cloud(), state.view_state)

    def request(self, state: EpisodeState) -> NetworkRequest:
        """What this episode's network is shown in ``state``, for a batched decision
        (:func:`nbv.policies.lockstep.run_lockstep`)."""
        return NetworkRequest(self, state.cloud(), state.view_state)

    def __call__(self, state: EpisodeState) -> int:
        return self.decide(state.cloud(), state.view_state)
