"""A ``@hydra.main`` function as a command: a refused run says why in one line and leaves nothing.

Two moments refuse a run:

- hydra composes the config (an unknown key, a value of the wrong type, a group option that does
  not exist, a bad override): :func:`entry_point` turns hydra's report into one line on stderr
  and exit status 2. Nothing exists yet: hydra makes the run folder only after composing.
- the task builds its settings (a value out of range, fields that do not fit together, a file
  that is not there): :func:`refuse` removes the run folder hydra has just made for the task,
  when it holds nothing but hydra's own files and an empty job log, then does the same.

Either way the last line on stderr is ``<prog>: <what is wrong>`` and the status is 2.
``HYDRA_FULL_ERROR=1`` in the environment keeps hydra's own report of composition errors.

Once the work runs, three faults still end in one line: an output another live process holds
(:class:`~nbv.utils.lock.OutputBusy`) and a bad input file met mid-work
(:class:`~nbv.utils.artefacts.ArtefactError`), status 2; a write that ran out of space (a full
disk, a quota, a file-size limit), status :data:`NO_SPACE_STATUS`, after which the same command
goes on where it stopped.

:func:`command` builds every entry point this way, so that a ``__main__`` module holds only its
own work: ``main = command(PROG, "eval", start, finish)`` and ``if __name__ == "__main__": main()``.
"""

from __future__ import annotations

import logging
import os
import shutil
import sys
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any, NoReturn, TypeVar

import hydra
from hydra.core.hydra_config import HydraConfig
from hydra.errors import HydraException
from omegaconf.errors import OmegaConfBaseException

from nbv.config.schema import describe
from nbv.utils.artefacts import ArtefactError, out_of_space
from nbv.utils.lock import OutputBusy

log = logging.getLogger(__name__)

#: The hydra configs of every entry point (``conf/`` at the repository's root).
CONF_DIR = str(Path(__file__).resolve().parents[2] / "conf")

T = TypeVar("T")

#: What hydra writes into ``<run folder>/<hydra.output_subdir>`` before the task starts.
HYDRA_FILES = ("config.yaml", "hydra.yaml", "overrides.yaml")
#: Exit status of a refused run.
REFUSED = 2
#: Exit status of a run stopped by a full disk (or a file-size limit): EX_TEMPFAIL, "try again".
NO_SPACE_STATUS = 75


def _one_line(message: object) -> str:
    return "; ".join(line.strip() for line in str(message).splitlines() if line.strip())


def fail(prog: str, message: object) -> NoReturn:
    """Print ``<prog>: <message>`` (one line) on stderr and exit with status 2."""
    print(f"{prog}: {_one_line(message)}", file=sys.stderr)
    sys.exit(REFUSED)


def given_keys() -> set[str]:
    """The keys set on this command's line (hydra's task overrides): ``{"methods",
    "checkpoints.pcnbv", ...}``; empty outside a hydra task."""
    if not HydraConfig.initialized():
        return set()
    return {o.split("=", 1)[0].lstrip("+~") for o in HydraConfig.get().overrides.task}


def check_given_files(files: dict[str, object]) -> None:
    """Refuse a file named on the command line (a key of :func:`given_keys`) that is not there:
    what the user named is used or the run is refused, never replaced by a default.

    Args:
        files: setting key -> the path it holds (None: not set), for the keys that name an
            input file this run will read.

    Raises:
        ValueError: naming the first such key and its path.
    """
    given = given_keys()
    for key, path in files.items():
        if key in given and path is not None and not Path(str(path)).is_file():
            raise ValueError(
                f"{key}={path}: no such file (a file named on the command line is used or the "
                "run is refused; leave the key out for the default)"
            )


def stop_if_out_of_space(prog: str, err: BaseException) -> None:
    """End the program with one line and :data:`NO_SPACE_STATUS` when ``err`` is a write that
    ran out of room (:func:`~nbv.utils.artefacts.out_of_space`); return otherwise.

    Every writer writes through a temporary file (:mod:`nbv.utils.atomic`), so what is under
    its final name is whole, and the same command run again once there is room goes on from
    where this one stopped."""
    if not out_of_space(err):
        return
    where = getattr(err, "filename", None)
    reason = getattr(err, "strerror", None) or _one_line(err)
    print(f"{prog}: {where + ': ' if where else ''}{reason}; nothing half-written was kept: "
          "free some space and run the same command again, it goes on from where it stopped",
          file=sys.stderr)  # fmt: skip
    sys.exit(NO_SPACE_STATUS)


def entry_point(prog: str, hydra_main: Callable[[], object]) -> None:
    """Run ``hydra_main`` (a ``@hydra.main`` function); a config hydra refuses ends the program
    with one line on stderr and status 2 instead of hydra's multi-line report and status 1.

    Hydra raises instead of reporting when ``HYDRA_FULL_ERROR`` is set, so it is set while
    ``hydra_main`` runs; when the environment sets it already, hydra's report is kept.
    """
    if os.environ.get("HYDRA_FULL_ERROR"):
        hydra_main()
        return
    os.environ["HYDRA_FULL_ERROR"] = "1"
    try:
        hydra_main()
    except (HydraException, OmegaConfBaseException) as err:
        fail(prog, describe(err))
    finally:
        os.environ.pop("HYDRA_FULL_ERROR", None)


def _untouched(run_dir: Path, scratch: Iterable[str]) -> bool:
    """``run_dir`` holds only hydra's files, an empty job log and the ``scratch`` files."""
    hc = HydraConfig.get()
    subdir = Path(hc.output_subdir) if hc.output_subdir else None
    allowed = {subdir / name for name in HYDRA_FILES} if subdir else set()
    allowed |= {Path(name) for name in scratch}
    job_log = Path(f"{hc.job.name}.log")
    for path in run_dir.rglob("*"):
        rel = path.relative_to(run_dir)
        if rel in allowed or (path.is_dir() and rel == subdir):
            continue
        if rel == job_log and path.is_file() and path.stat().st_size == 0:
            continue
        return False
    return True


def _release_logs(run_dir: Path) -> None:
    """Close and drop the logging file handlers that write into ``run_dir``."""
    root = logging.getLogger()
    for handler in list(root.handlers):
        if isinstance(handler, logging.FileHandler):
            if Path(handler.baseFilename).resolve().is_relative_to(run_dir):
                root.removeHandler(handler)
                handler.close()


def remove_run_dir(scratch: Iterable[str] = ()) -> bool:
    """Remove the folder hydra made for this job, if the job left nothing of its own there.

    The folder goes when it holds nothing but hydra's saved config, an empty job log and the
    ``scratch`` files (names relative to the folder); then so do the parents it leaves empty,
    up to the working directory (only those inside it). A folder that held anything else, from
    an earlier run or from this one, stays.

    Returns:
        True when no run folder remains (removed, or there was none).
    """
    if not HydraConfig.initialized():
        return True
    run_dir = Path(HydraConfig.get().runtime.output_dir).resolve()
    cwd = Path.cwd().resolve()
    if not run_dir.is_dir():
        return True
    if cwd.is_relative_to(run_dir) or not _untouched(run_dir, scratch):
        return False
    _release_logs(run_dir)
    shutil.rmtree(run_dir)
    for parent in run_dir.parents:
        if parent == cwd or not parent.is_relative_to(cwd):
            break
        try:
            parent.rmdir()
        except OSError:  # not empty: something else lives there
            break
    return True


def _to_job_log(prog: str, message: str) -> None:
    """Write the refusal into the job's log files only (the console gets :func:`fail`'s line)."""
    record = log.makeRecord(log.name, logging.ERROR, __file__, 0, "%s: %s", (prog, message), None)
    for handler in logging.getLogger().handlers:
        if isinstance(handler, logging.FileHandler):
            handler.handle(record)


def refuse(prog: str, err: BaseException, scratch: Iterable[str] = ()) -> NoReturn:
    """End a hydra task that cannot run: remove its run folder when the task left nothing there
    (:func:`remove_run_dir`; else the job log gets the message), then one line and status 2.

    Args:
        prog: the command's name, the line's prefix.
        err: what refused the run (its message names the key).
        scratch: files the task wrote before it knew the run would go ahead, that do not count
            as work (e.g. ``run.json``).
    """
    message = _one_line(
        describe(err) if isinstance(err, HydraException | OmegaConfBaseException) else err
    )
    if not remove_run_dir(scratch):
        _to_job_log(prog, message)
    fail(prog, message)


def command(
    prog: str,
    config_name: str,
    start: Callable[[Any], T],
    finish: Callable[[T], object] | None = None,
    scratch: Iterable[str] = (),
) -> Callable[[], None]:
    """An entry point: hydra composes ``conf/<config_name>.yaml``, ``start(cfg)`` checks the
    settings and the input (and may do the work), ``finish(start's result)`` does the rest.

    A ``ValueError`` from ``start`` (a bad setting or input file; its message names it) refuses
    the run with :func:`refuse`: one line, status 2, no run folder left. A config hydra cannot
    compose is refused alike (:func:`entry_point`). ``finish`` runs after that point: its errors
    are the program's own and keep their traceback.

    Args:
        prog: the command's name (``nbv.eval``), the prefix of a refusal's line.
        config_name: the primary config under ``conf/``.
        start: composed config -> what ``finish`` needs.
        finish: the work after the checks, or None.
        scratch: files ``start`` writes that do not count as work (:func:`refuse`).

    Returns:
        The program: call it from ``if __name__ == "__main__":``.
    """
    scratch = tuple(scratch)

    def work(cfg: Any) -> None:
        try:
            state = start(cfg)
        except ValueError as err:
            refuse(prog, err, scratch)
        if finish is None:
            return
        try:
            finish(state)
        except (OutputBusy, ArtefactError) as err:
            # The work's own lock, taken as it starts writing; a bad input file met mid-work
            # (what is written so far is whole, and a rerun once it is mended goes on).
            fail(prog, err)

    def task(cfg: Any) -> None:
        try:
            work(cfg)
        except (OSError, RuntimeError) as err:
            stop_if_out_of_space(prog, err)
            raise

    # The job's name comes from each config's hydra.job.name, not from this module.
    main = hydra.main(config_path=CONF_DIR, config_name=config_name, version_base="1.3")(task)
    return lambda: entry_point(prog, main)
