"""A trained PCNBV / PCNBV-sph checkpoint as a view-selection policy."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from nbv.geometry.clouds import farthest_points
from nbv.policies.episode import EpisodeState
from nbv.policies.inputs import cloud_or_origin, record_time, safe_signature


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
        the network is shown)."""
        import torch

        from nbv.models.precision import autocast, flush_denormals

        t0 = time.perf_counter()
        points = self.features(cloud)
        t1 = time.perf_counter()
        device = next(self.model.parameters()).device
        with torch.inference_mode(), flush_denormals(), autocast(self.precision, device):
            x = torch.from_numpy(np.ascontiguousarray(points, dtype=np.float32))[None]
            s = torch.from_numpy(np.asarray(view_state, dtype=np.float32))[None]
            scores = self.model(x.to(device), s.to(device)).float().cpu()[0].numpy()
        record_time(self.timings, "signature" if self.input == "signature" else "sampling", t1 - t0)
        record_time(self.timings, "network", time.perf_counter() - t1)
        return scores

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
        import torch

        from nbv.models.inference import masked_argmax  # refuses NaN scores and a full state

        scores = torch.from_numpy(self.predict(cloud, view_state))[None]
        mask = torch.from_numpy(np.asarray(view_state if visited is None else visited, bool))
        return int(masked_argmax(scores, mask[None])[0])

    def view_scores(self, state: EpisodeState) -> np.ndarray:
        """(V,) the scores this policy picks by in ``state`` (see :meth:`predict`)."""
        return self.predict(state.cloud(), state.view_state)

    def __call__(self, state: EpisodeState) -> int:
        return self.decide(state.cloud(), state.view_state)
