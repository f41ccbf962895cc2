"""The field's metrics of an episode, beside coverage AUC and VIG (``EpisodeRecord.metrics``).

Computed once per episode from its views and the model's record, after the episode ran (they
do not change what a method picks, so stored runs and the episode log's identity stay valid):

* ``final_coverage``: the last value of the coverage curve;
* ``full_coverage``: the coverage all views of the viewspace reach together (the model's
  ceiling); ``views_to_90`` and ``views_to_95``: the number of views (the start view counts)
  after which the episode first reaches 90 % and 95 % of it, None when it never does within the
  episode, and then ``censored_90`` / ``censored_95`` is True;
* ``chamfer_accuracy`` (reconstruction to ground truth), ``chamfer_completeness`` (ground truth
  to reconstruction), ``chamfer`` (their mean), and ``precision_``, ``recall_``, ``fscore_`` at
  ``eps`` and ``2eps`` (the dataset's coverage distance): the accumulated cloud of the episode's
  views (the dataset's stored points, the normalised object frame) against the ground-truth
  points (:mod:`nbv.geometry.reconstruction_metrics`);
* ``path_length``: the great-circle arcs between consecutive views at the viewspace's radius
  (the mean distance of its cameras from the object's centre); ``shortest_path``: the shortest
  open path from the start view through the same views (exact), what a one-shot plan's views
  cost in their best order; NaN beyond :data:`~nbv.geometry.reconstruction_metrics.MAX_TOUR_VIEWS`.

:class:`ModelMetrics` keeps, per model, the ground truth's KD-tree (built once), each view's
distances (:class:`~nbv.geometry.reconstruction_metrics.ViewDistances`, each view queried once)
and each viewspace's arc matrix, so an episode's metrics cost a few vector operations.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from nbv.dataset.records import ModelData
from nbv.geometry.reconstruction_metrics import (
    MAX_TOUR_VIEWS,
    ViewDistances,
    great_circle_matrix,
    path_length,
    shortest_open_path,
    views_to_reach,
)
from nbv.geometry.scores import coverage_from_bits

#: The fractions of the viewspace's total coverage whose views-to-reach are recorded, and the
#: suffix of their keys.
REACH_FRACTIONS: dict[str, float] = {"90": 0.90, "95": 0.95}
#: The F-score thresholds, as multiples of the dataset's ``eps``.
FSCORE_MULTIPLES = (1, 2)
#: How a metric is aggregated over episodes: ``mean`` (the mean of its finite values), or
#: ``censored`` (views to reach a share of the coverage: the mean over the episodes that reach
#: it, the censored ones counted, and the restricted count paired; :mod:`nbv.eval.metric_tables`).
AGGREGATIONS = ("mean", "censored")


@dataclass(frozen=True)
class Metric:
    """One metric of an episode: the one declaration the evaluator, the report's tables and the
    plots read (docs/development.md, "Adding a metric").

    Attributes:
        key: its key in an episode's ``metrics`` (results.json, the episode log, summary.csv).
        title: its column title in the report's tables.
        digits: the digits it is written with.
        lower_better: a lower value is better (Chamfer distance, views to reach, path).
        paired: the report gives its paired differences against spread and random.
        aggregate: how it is aggregated over episodes (:data:`AGGREGATIONS`).
        tabled: a column of the report's table of means.
        table_digits: its digits in that table; None: ``digits``.
        panel: its panel's title in metrics.png; None: not drawn.
        compute: ``(model metrics, viewspace, views, coverage curve) -> value`` (a float, NaN
            where undefined); None for the metrics :meth:`ModelMetrics.episode` computes
            together (they share the ground truth's distances).
    """

    key: str
    title: str
    digits: int = 3
    lower_better: bool = False
    paired: bool = False
    aggregate: str = "mean"
    tabled: bool = True
    table_digits: int | None = None
    panel: str | None = None
    compute: Callable[[ModelMetrics, str, list[int], list[float]], float] | None = None

    def __post_init__(self) -> None:
        if self.aggregate not in AGGREGATIONS:
            raise ValueError(f"metric {self.key}: aggregate={self.aggregate!r}; allowed: "
                             f"{AGGREGATIONS}")  # fmt: skip

    @property
    def summary_key(self) -> str:
        """Its key in a group's summary (:func:`nbv.eval.statistics.summaries`): a censored
        metric's restricted count, else its key."""
        return (
            f"restricted_{self.key.rsplit('_', 1)[1]}" if self.aggregate == "censored" else self.key
        )


#: Every metric of an episode, in report order (the one place that declares them).
METRICS: tuple[Metric, ...] = (
    Metric("final_coverage", "final coverage", paired=True, panel="final coverage"),
    Metric("full_coverage", "full coverage", tabled=False),
    Metric("views_to_90", "views to 90 %", 2, True, paired=True, aggregate="censored",
           panel="views to 90 % (censored: n + 1)"),
    Metric("views_to_95", "views to 95 %", 2, True, paired=True, aggregate="censored"),
    Metric("chamfer_accuracy", "Chamfer acc.", 4, True),
    Metric("chamfer_completeness", "Chamfer comp.", 4, True),
    Metric("chamfer", "Chamfer", 5, True, paired=True, table_digits=4,
           panel="Chamfer distance (lower: better)"),
    Metric("precision_eps", "precision eps", tabled=False),
    Metric("recall_eps", "recall eps", tabled=False),
    Metric("fscore_eps", "F-score eps", paired=True),
    Metric("precision_2eps", "precision 2 eps", tabled=False),
    Metric("recall_2eps", "recall 2 eps", tabled=False),
    Metric("fscore_2eps", "F-score 2 eps", paired=True, panel="F-score at 2 eps"),
    Metric("path_length", "path", 2, True, paired=True, panel="camera path (lower: better)"),
    Metric("shortest_path", "shortest path", 2, True),
)  # fmt: skip


def paired_metrics() -> tuple[Metric, ...]:
    """The metrics with paired intervals in the report, in report order."""
    return tuple(m for m in METRICS if m.paired)


def tabled_metrics() -> tuple[Metric, ...]:
    """The columns of the report's table of means, in report order."""
    return tuple(m for m in METRICS if m.tabled)


def mean_keys() -> tuple[str, ...]:
    """The keys of the metrics aggregated by their mean (summary.csv's columns), in order."""
    return tuple(m.key for m in METRICS if m.aggregate == "mean")


def plot_panels() -> tuple[tuple[str, str], ...]:
    """metrics.png's panels: (summary key, title), in order."""
    return tuple((m.summary_key, m.panel) for m in METRICS if m.panel is not None)


class ModelMetrics:
    """The metrics of one model's episodes (see the module docstring).

    Args:
        model: the model's record, with the viewspaces its episodes run on.
        eps: the dataset's coverage distance (the F-scores' base threshold).
    """

    def __init__(self, model: ModelData, eps: float) -> None:
        self.model = model
        self.eps = float(eps)
        self._gt_tree: cKDTree | None = None
        self._views: dict[str, ViewDistances] = {}
        self._arcs: dict[str, np.ndarray] = {}
        self._full: dict[str, float] = {}

    def _distances(self, viewspace: str) -> ViewDistances:
        if viewspace not in self._views:
            if self._gt_tree is None:
                self._gt_tree = cKDTree(np.asarray(self.model.gt_points, dtype=np.float64))
            view = self.model.views[viewspace]
            self._views[viewspace] = ViewDistances(
                self.model.gt_points, view.points, view.offsets, self.eps, FSCORE_MULTIPLES,
                gt_tree=self._gt_tree,
            )  # fmt: skip
        return self._views[viewspace]

    def full_coverage(self, viewspace: str) -> float:
        """The coverage of all the viewspace's views together."""
        if viewspace not in self._full:
            view = self.model.views[viewspace]
            every = np.ones(len(view.poses), dtype=bool)
            self._full[viewspace] = coverage_from_bits(
                view.coverage, every, len(self.model.gt_points)
            )
        return self._full[viewspace]

    def arcs(self, viewspace: str) -> np.ndarray:
        """(V, V) great-circle distances between the viewspace's cameras."""
        if viewspace not in self._arcs:
            self._arcs[viewspace] = great_circle_matrix(self.model.views[viewspace].poses[:, :3, 3])
        return self._arcs[viewspace]

    def episode(self, viewspace: str, views: list[int], coverage: list[float]) -> dict:
        """The metrics of one episode: its views in order (start first) and coverage curve.

        Returns:
            The keys of the module docstring: floats (NaN where undefined), ``views_to_*`` an
            int or None, ``censored_*`` a bool.
        """
        out: dict = {"final_coverage": float(coverage[-1])}
        full = self.full_coverage(viewspace)
        out["full_coverage"] = float(full)
        for name, fraction in REACH_FRACTIONS.items():
            reached = views_to_reach(coverage, fraction * full)
            out[f"views_to_{name}"] = reached
            out[f"censored_{name}"] = reached is None
        out.update(self._distances(viewspace).scores(views))
        arcs = self.arcs(viewspace)
        out["path_length"] = path_length(arcs, views)
        if len(views) <= MAX_TOUR_VIEWS:
            out["shortest_path"] = shortest_open_path(arcs[np.ix_(views, views)])[0]
        else:
            out["shortest_path"] = float("nan")
        for metric in METRICS:
            if metric.compute is not None:
                out[metric.key] = float(metric.compute(self, viewspace, views, coverage))
        return out


def fill_metrics(records: list, model: ModelData, eps: float) -> int:
    """Compute the metrics of the records that lack them (episodes read back from a log written
    before the metrics existed), in place.

    Args:
        records: :class:`nbv.eval.protocol.EpisodeRecord` of the model.
        model: its record, with every viewspace those records ran on.
        eps: the dataset's coverage distance.

    Returns:
        How many records were filled.
    """
    missing = [r for r in records if not r.metrics]
    if missing:
        metrics = ModelMetrics(model, eps)
        for r in missing:
            r.metrics = metrics.episode(r.viewspace, r.views, r.coverage)
    return len(missing)
