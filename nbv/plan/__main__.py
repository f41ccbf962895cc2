"""``python -m nbv.plan mesh=FILE | captures=FOLDER [method=...] [viewspace.kind=...] [key=value]``.

Settings: ``conf/plan.yaml`` (schema: :mod:`nbv.plan.config`). From a mesh it plays a whole
episode on ray-cast captures (coverage by view against the mesh; ``save_captures=K`` also writes
the first K views as a capture folder); from a capture folder it plans the next view, or a
one-shot planner's whole remaining plan. Writes plan.json, cloud.ply, plan.png and plan.html into
the run folder (:mod:`nbv.plan.output`). A refused setting or bad input ends with one line on
stderr naming the key or file, exit status 2, and no run folder left behind
(:mod:`nbv.config.cli`).
"""

import logging

import hydra
from omegaconf import DictConfig

from nbv.config.cli import entry_point, refuse
from nbv.plan.config import settings_from_config

PROG = "nbv.plan"
# Named, not __name__ (which is "__main__" under `python -m`), so the job log says who speaks.
log = logging.getLogger("nbv.plan")


@hydra.main(config_path="../../conf", config_name="plan", version_base="1.3")
def main(cfg: DictConfig) -> None:
    from nbv.plan.mesh import plan_mesh, save_episode_captures
    from nbv.plan.next_view import plan_captures
    from nbv.plan.output import write_outputs

    try:
        settings = settings_from_config(cfg)
        if settings.mesh is not None:
            result, depth = plan_mesh(settings)
        else:
            result, depth = plan_captures(settings), None
    except ValueError as err:  # bad settings or input: one line, nothing written
        refuse(PROG, err)
    written = write_outputs(settings, result)
    if settings.save_captures:
        folder = save_episode_captures(settings, result, depth)
        log.info("saved %d captures to %s", settings.save_captures, folder)
    if result.coverage:
        log.info("coverage by view: %s", " ".join(f"{c:.3f}" for c in result.coverage))
    log.info("%s: next view %d, plan %s; wrote %s", settings.method, result.chosen[0],
             result.chosen, ", ".join(str(p) for p in written))  # fmt: skip
    print(f"next view {result.chosen[0]}; plan {result.chosen}; {settings.out_dir / 'plan.json'}")


if __name__ == "__main__":
    entry_point(PROG, main)
