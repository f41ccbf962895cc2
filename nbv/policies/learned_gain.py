"""``ig_learned``: the occupancy map of ``ig``, with candidates ranked by a learned score.

``ig`` ranks candidates by one count (the unknown voxels their rays would cross). Here each
candidate's rays give several (:mod:`nbv.infogain.view_features`: the unknown volume and area it
faces, the rear sides and frontier voxels it would see, how far the unknown region lies, its
angle to the captured views), and a small perceptron trained on the training categories' true
coverage gains (:mod:`nbv.infogain.gain_scorer`, ``python -m train.scorer``) weighs them. The policy
reads what ``ig`` reads: the captured views' points and poses and the candidates' poses.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from nbv.geometry.camera import Intrinsics
from nbv.infogain.gain import view_gains
from nbv.infogain.gain_scorer import GainScorer, load_scorer
from nbv.infogain.settings import InfoGainSettings
from nbv.infogain.view_features import unvisited_features
from nbv.policies.episode import EpisodeState
from nbv.policies.infogain import InfoGainPolicy
from nbv.policies.inputs import record_time
from nbv.utils.selection import masked_argmax


@dataclass
class LearnedGainPolicy(InfoGainPolicy):
    """The unvisited view of the highest learned score on the map of the captured views
    (ties to the lowest index). ``last_gains`` holds the chosen view's ``ig`` gain, and a pick
    whose rays see no unknown voxel counts as ``zero_gain``."""

    scorer: GainScorer | None = field(default=None, kw_only=True)

    @classmethod
    def from_checkpoint(
        cls, path: str | Path, intrinsics: Intrinsics, settings: InfoGainSettings | None = None
    ) -> LearnedGainPolicy:
        """The policy of the scorer file ``path`` (:func:`nbv.infogain.gain_scorer.load_scorer`;
        ``ScorerError`` names a bad file) on the map of ``settings`` (default: ``ig``'s
        defaults, on which the shipped scorer was trained)."""
        return cls(settings or InfoGainSettings(), intrinsics, scorer=load_scorer(path))

    def view_scores(self, state: EpisodeState) -> np.ndarray:
        """(V,) the learned scores this policy picks by in ``state`` (-inf for visited views)."""
        if self.scorer is None:
            raise ValueError(
                "LearnedGainPolicy needs a scorer (nbv.infogain.gain_scorer.load_scorer)"
            )
        t0 = time.perf_counter()
        self.update(state)
        t1 = time.perf_counter()
        view = state.views
        candidates = self.candidate_voxels(view.poses)
        open_ = np.flatnonzero(~state.view_state)
        features = unvisited_features(self.occupancy, candidates, view.poses[:, :3, 3], state.order)
        scores = np.full(len(candidates), -np.inf)
        scores[open_] = self.scorer.scores(features[open_])
        record_time(self.timings, "map", t1 - t0)
        record_time(self.timings, "gains", time.perf_counter() - t1)
        return scores

    def __call__(self, state: EpisodeState) -> int:
        choice = masked_argmax(self.view_scores(state), state.view_state)
        candidates = self.candidate_voxels(state.views.poses)
        gain = view_gains(self.occupancy, candidates[choice : choice + 1], self.settings.metric)
        self.last_gains = [float(gain[0])]
        self.counts["planned"] += 1
        self.counts["zero_gain"] += int(gain[0] <= 0)
        return choice
