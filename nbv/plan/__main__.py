"""``python -m nbv.plan mesh=FILE | captures=FOLDER [method=...] [viewspace.kind=...] [key=value]``.

Settings: ``conf/plan.yaml`` (declared by :class:`nbv.plan.config.PlanSettings`). From a mesh it
plays a whole episode on ray-cast captures (coverage by view against the mesh;
``save_captures=K`` also writes the first K views as a capture folder); from a capture folder it
plans the next view, or a one-shot planner's whole remaining plan (a
:class:`nbv.scan.planner.Planner` on the folder's views, one decision). Writes plan.json,
cloud.ply, reconstruction.ply (the depth views fused), plan.png and plan.html into the run
folder (:mod:`nbv.plan.output`). A refused setting or bad
input ends with one line on stderr naming the key or file, exit status 2, and no run folder left
behind (:mod:`nbv.config.cli`).
"""

import logging

from nbv.models.threads import configure_openmp

# Before torch is imported (nbv.models.threads): a robot's computer is rarely idle.
configure_openmp()

from nbv.config.cli import check_given_files, command  # noqa: E402
from nbv.plan.config import ENTRY  # noqa: E402

PROG = "nbv.plan"
# Named, not __name__ (which is "__main__" under `python -m`), so the job log says who speaks.
log = logging.getLogger("nbv.plan")


def start(cfg) -> tuple:
    """The settings, the input read and the plan made: nothing is written yet."""
    from nbv.plan.mesh import plan_mesh, reconstruct_episode
    from nbv.scan.planner import Planner

    settings = ENTRY.build(cfg)
    check_given_files({"checkpoint": settings.checkpoint})
    if settings.mesh is not None:
        result, depth = plan_mesh(settings)
        result.reconstruction = reconstruct_episode(settings, result, depth)
    else:
        planner = Planner.load(settings.captures, settings, views=settings.views)
        result, depth = planner.decide(), None
        result.reconstruction = planner.reconstruct()
        if result.reconstruction is None:
            result.notes.append("no reconstruction: every view is a point cloud")
    fused = result.reconstruction
    if fused is not None:
        log.info("reconstruction: %d views fused at voxel %.4g: %d vertices, %d triangles",
                 len(fused.views), fused.voxel, len(fused.vertices),
                 len(fused.triangles))  # fmt: skip
        if fused.scores is not None:
            log.info("reconstruction against the mesh: %s",
                     ", ".join(f"{k} {v:.4g}" for k, v in fused.scores.items()))  # fmt: skip
    return settings, result, depth


def finish(started: tuple) -> None:
    """Write the plan's files (and the saved captures) and say what was planned."""
    from nbv.plan.mesh import save_episode_captures
    from nbv.plan.output import write_outputs

    settings, result, depth = started
    written = write_outputs(settings, result)
    if settings.save_captures:
        folder = save_episode_captures(settings, result, depth)
        log.info("saved %d captures to %s", settings.save_captures, folder)
    if result.coverage:
        log.info("coverage by view: %s", " ".join(f"{c:.3f}" for c in result.coverage))
    log.info("%s: next view %d, plan %s; wrote %s", settings.method, result.chosen[0],
             result.chosen, ", ".join(str(p) for p in written))  # fmt: skip
    print(f"next view {result.chosen[0]}; plan {result.chosen}; {settings.out_dir / 'plan.json'}")


main = command(PROG, "plan", start, finish)

if __name__ == "__main__":
    main()
