"""Draw a real object's captured, completed and true clouds after 1, 2 and 3 views (a developer
tool: the picture of docs/methods.md).

    python scripts/draw_completion.py --mesh 035_power_drill --out docs/completion_drill.png

The mesh is a YCB object (``source=ycb``), normalised as a dataset normalises it, ray cast from
the original viewspace at the dataset's camera; the views are the start view and the next ones
of the spread order. "Completed" is the captured cloud and the shipped network's predicted
points it lacks (:meth:`nbv.models.completion_inference.Completer.complete`).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from nbv.assets.meshes import sample_surface  # noqa: E402
from nbv.assets.weights import FOLDER  # noqa: E402
from nbv.dataset.sources import list_models, load_normalised  # noqa: E402
from nbv.eval.completion_quality import cd_l1  # noqa: E402
from nbv.geometry.camera import Intrinsics, backproject, viewspace_poses  # noqa: E402
from nbv.geometry.raycast import raycast_depth  # noqa: E402
from nbv.geometry.viewspace import get_viewspace, spread_views, unit_directions  # noqa: E402
from nbv.models.completion_inference import Completer  # noqa: E402
from nbv.utils.atomic import atomic_path  # noqa: E402
from nbv.utils.seeding import named_rng  # noqa: E402


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="scripts/draw_completion.py")
    parser.add_argument("--mesh", default="035_power_drill", help="a YCB object's key")
    parser.add_argument("--start", type=int, default=1, help="the start view")
    parser.add_argument("--out", type=Path, default=Path("docs/completion_drill.png"))
    args = parser.parse_args(argv)
    models = {m.key: m for m in list_models("ycb")}
    if args.mesh not in models:
        parser.error(f"--mesh {args.mesh}: not a YCB key; e.g. {', '.join(list(models)[:5])}")
    mesh, _, _ = load_normalised(models[args.mesh], 0)
    rng = named_rng(0, "draw-completion", args.mesh)
    truth = sample_surface(mesh, 16384, rng).astype(np.float64)
    viewspace = get_viewspace("original")
    poses = viewspace_poses(viewspace)
    closed = np.zeros(len(viewspace), dtype=bool)
    closed[args.start] = True
    order = np.array([args.start, *spread_views(unit_directions(viewspace), closed, 2, rng)])
    camera = Intrinsics()
    depth = raycast_depth(mesh.vertices, mesh.faces, poses[order], camera)
    views = [backproject(d, camera, p) for d, p in zip(depth, poses[order], strict=True)]
    views = [v[rng.choice(len(v), min(2048, len(v)), replace=False)] for v in views]
    completer = Completer.from_checkpoint(FOLDER / "completion.pt")
    fig = plt.figure(figsize=(10, 10))
    for row in range(3):
        captured = np.concatenate(views[: row + 1])
        completed = completer.complete(captured)
        clouds = [("captured", captured), ("completed", completed), ("true", truth)]
        for col, (name, cloud) in enumerate(clouds):
            ax = fig.add_subplot(3, 3, 3 * row + col + 1, projection="3d")
            pick = rng.choice(len(cloud), min(4000, len(cloud)), replace=False)
            shown = cloud[pick]
            new = (pick >= len(captured)) if name == "completed" else np.zeros(len(pick), bool)
            # Y is up in the normalised frame: draw it as matplotlib's z.
            ax.scatter(shown[:, 0], shown[:, 2], shown[:, 1], s=0.5,
                       c=np.where(new, "#d62728", "#1f77b4"))  # fmt: skip
            ax.set_xlim(-0.5, 0.5), ax.set_ylim(-0.5, 0.5), ax.set_zlim(-0.5, 0.5)
            ax.set_axis_off()
            title = f"{name}, {row + 1} view{'s' * (row > 0)}"
            if name != "true":
                title += f"\nCD-L1 {cd_l1(cloud, truth):.4f}"
            ax.set_title(title, fontsize=9)
    fig.suptitle(f"YCB {args.mesh}: views {order.tolist()} (red: predicted points)", fontsize=10)
    fig.tight_layout()
    with atomic_path(args.out) as tmp:
        fig.savefig(tmp, dpi=90, format="png")
    print(args.out)


if __name__ == "__main__":
    main()
