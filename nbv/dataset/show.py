"""``python -m nbv.dataset.show dataset=<file or folder> key=<model> [out=PNG]``: draw a model's
views.

The picture holds one panel per view (the depth image when the dataset kept it, else the view's
stored points projected back into its camera, coloured by depth) and the merged cloud of all views
beside the ground truth. Settings: ``conf/dataset_show.yaml`` (declared by :class:`ShowSettings`).
A model or viewspace the dataset does not hold ends with one line on stderr and exit status 2.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from nbv.config.cli import command  # noqa: E402
from nbv.config.schema import PathsConfig  # noqa: E402
from nbv.config.settings import Entry  # noqa: E402
from nbv.dataset.reader import Dataset, open_dataset  # noqa: E402
from nbv.dataset.records import ModelData  # noqa: E402
from nbv.geometry.camera import Intrinsics, project  # noqa: E402
from nbv.utils.atomic import save_figure

PROG = "nbv.dataset.show"
# Named, not __name__ (which is "__main__" under `python -m`), so the job log says who speaks.
log = logging.getLogger("nbv.dataset.show")


def depth_panel(ax, model: ModelData, viewspace: str, v: int, intrinsics: Intrinsics) -> None:
    """Draw view ``v``'s depth image (or its projected points) into ``ax``."""
    view = model.views[viewspace]
    if view.depth is not None:
        depth = view.depth[v].astype(np.float32)
        ax.imshow(np.where(np.isfinite(depth), depth, np.nan), cmap="viridis")
    else:
        uv, z = project(view.view_points(v), intrinsics, view.poses[v])
        ax.scatter(uv[:, 0], uv[:, 1], c=z, s=0.3, cmap="viridis", linewidths=0)
        ax.set_xlim(0, intrinsics.width)
        ax.set_ylim(intrinsics.height, 0)
        ax.set_aspect("equal")
    ax.set_xticks([])
    ax.set_yticks([])
    ax.set_title(str(v), fontsize=7, pad=2)


def draw_model(model: ModelData, intrinsics: Intrinsics, viewspace: str, out: Path) -> Path:
    """Write the PNG of one model's views and clouds; returns its path."""
    if viewspace not in model.views:
        raise KeyError(f"viewspace {viewspace!r} not stored; have {sorted(model.views)}")
    n_views = len(model.views[viewspace].poses)
    cols = 8
    rows = -(-n_views // cols)
    fig = plt.figure(figsize=(cols * 1.6 + 6, max(rows, 3) * 1.3 + 0.6))
    grid = fig.add_gridspec(max(rows, 3), cols + 4)
    for v in range(n_views):
        depth_panel(fig.add_subplot(grid[v // cols, v % cols]), model, viewspace, v, intrinsics)
    view = model.views[viewspace]
    ax = fig.add_subplot(grid[:, cols:], projection="3d")
    gt = model.gt_points
    ax.scatter(gt[:, 0], gt[:, 2], gt[:, 1], s=0.2, c="lightgray", label="ground truth")
    merged = view.points[:: max(1, len(view.points) // 20000)]
    ax.scatter(merged[:, 0], merged[:, 2], merged[:, 1], s=0.3, c=merged[:, 1], cmap="plasma")
    cams = view.poses[:, :3, 3]
    ax.scatter(cams[:, 0], cams[:, 2], cams[:, 1], c="red", s=8, label="cameras")
    ax.set_box_aspect((1, 1, 1))
    ax.set_xlabel("x")
    ax.set_ylabel("z")
    ax.set_zlabel("y (up)")
    ax.legend(loc="upper left", fontsize=7)
    fig.suptitle(f"{model.key} ({model.category}, {model.split}), viewspace {viewspace}")
    out.parent.mkdir(parents=True, exist_ok=True)
    save_figure(fig, out, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return out


@dataclass(frozen=True)
class ShowSettings:
    """The model whose views ``python -m nbv.dataset.show`` draws, and where the picture goes.

    Attributes:
        dataset: a shard file or a dataset folder.
        key: the model's key, e.g. ``chair_0000`` (not ``model``: that name is the networks'
            config group of ``conf/model/``).
        viewspace: the stored viewspace whose views are drawn.
        out: the PNG to write; null = ``<key>_<viewspace>.png`` in the working directory.
    """

    dataset: Path = field(kw_only=True)
    key: str = field(kw_only=True)
    viewspace: str = "original"
    out: Path | None = None

    @property
    def picture(self) -> Path:
        """The PNG's path."""
        return self.out or Path(f"{self.key}_{self.viewspace}.png")


ENTRY = Entry("dataset_show_schema", ShowSettings, extra=(("paths", PathsConfig),))


def start(cfg) -> tuple[ShowSettings, Dataset]:
    """The settings and the dataset, checked to hold the model and its viewspace."""
    s = ENTRY.build(cfg)
    dataset = open_dataset(s.dataset)
    if s.key not in dataset:
        raise ValueError(f"model {s.key!r} not in {s.dataset}; some keys: {list(dataset)[:8]}")
    if s.viewspace not in dataset.viewspaces:
        raise ValueError(f"viewspace {s.viewspace!r} not stored; have {sorted(dataset.viewspaces)}")
    return s, dataset


def finish(started: tuple[ShowSettings, Dataset]) -> None:
    s, dataset = started
    path = draw_model(dataset[s.key], dataset.intrinsics, s.viewspace, s.picture)
    log.info("wrote %s", path)


main = command(PROG, "dataset_show", start, finish)


if __name__ == "__main__":
    main()
