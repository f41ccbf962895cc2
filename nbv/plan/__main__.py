"""``python -m nbv.plan mesh=FILE | captures=FOLDER [method=...] [viewspace.kind=...] [key=value]``.

Settings: ``conf/plan.yaml`` (declared by :class:`nbv.plan.config.PlanSettings`). From a mesh it
plays a whole episode on ray-cast captures (coverage by view against the mesh;
``save_captures=K`` also writes the first K views as a capture folder); from a capture folder it
plans the next view, or a one-shot planner's whole remaining plan. Writes plan.json, cloud.ply,
plan.png and plan.html into the run folder (:mod:`nbv.plan.output`). A refused setting or bad
input ends with one line on stderr naming the key or file, exit status 2, and no run folder left
behind (:mod:`nbv.config.cli`).
"""

import logging

from nbv.config.cli import command
from nbv.plan.config import ENTRY

PROG = "nbv.plan"
# Named, not __name__ (which is "__main__" under `python -m`), so the job log says who speaks.
log = logging.getLogger("nbv.plan")


def start(cfg) -> tuple:
    """The settings, the input read and the plan made: nothing is written yet."""
    from nbv.plan.mesh import plan_mesh
    from nbv.plan.next_view import plan_captures

    settings = ENTRY.build(cfg)
    if settings.mesh is not None:
        result, depth = plan_mesh(settings)
    else:
        result, depth = plan_captures(settings), None
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
