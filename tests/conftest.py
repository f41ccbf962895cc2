"""Shared fixtures. ``slurm_cluster``: a real single-node SLURM, started once per test session.

``make test`` runs the tests in two processes (pytest-xdist, ``--dist loadgroup``): every test
that needs the SLURM cluster goes to one of them, so that one cluster runs at a time.
"""

import os
import shutil
import subprocess
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest
from needs import in_ci

SLURM_SCRIPTS = Path(__file__).parent / "slurm"


def _can_be_root() -> bool:
    """True when this process is root or may run `sudo -n` (as tests/slurm/start.sh does)."""
    if os.geteuid() == 0:
        return True
    if shutil.which("sudo") is None:
        return False
    return subprocess.run(["sudo", "-n", "true"], capture_output=True).returncode == 0


@dataclass(frozen=True)
class SlurmCluster:
    """A running cluster of tests/slurm/start.sh: ``conf`` is its slurm.conf, ``dir`` holds its
    state, spool and logs (slurmctld.log, slurmd.log)."""

    conf: Path
    dir: Path

    def log_tail(self, lines: int = 30) -> str:
        """The last ``lines`` lines of both daemons' logs, for failure messages."""
        parts = []
        for name in ("slurmctld.log", "slurmd.log"):
            path = self.dir / name
            if path.exists():
                tail = path.read_text(errors="replace").splitlines()[-lines:]
                parts.append(f"---- {path}\n" + "\n".join(tail))
        return "\n".join(parts)

    def run(
        self, *args: str | os.PathLike[str], cwd: Path | None = None, timeout: float = 300
    ) -> subprocess.CompletedProcess[str]:
        """Run a command against this cluster (SLURM_CONF set) and return it when it exits 0;
        otherwise fail the test with its output and the daemons' log tails."""
        env = {**os.environ, "SLURM_CONF": str(self.conf)}
        proc = subprocess.run(
            [str(a) for a in args],
            cwd=cwd,
            env=env,
            capture_output=True,
            text=True,
            timeout=timeout,
        )
        if proc.returncode != 0:
            pytest.fail(
                f"{' '.join(map(str, args))} exited with {proc.returncode}\n"
                f"stdout:\n{proc.stdout}\nstderr:\n{proc.stderr}\n{self.log_tail()}",
                pytrace=False,
            )
        return proc


@pytest.fixture(scope="session")
def slurm_cluster(tmp_path_factory: pytest.TempPathFactory) -> Iterator[SlurmCluster]:
    """Start tests/slurm/start.sh in a temporary folder, set SLURM_CONF for the session, and stop
    the daemons afterwards. Outside CI it skips when SLURM is not installed or root is out of
    reach; otherwise a cluster that does not start fails the tests instead of skipping them."""
    if not in_ci() and shutil.which("sbatch") is None:
        pytest.skip(
            "SLURM is not installed; enable these tests with `bash tests/slurm/install.sh` "
            "(root or passwordless sudo)"
        )
    if not in_ci() and not _can_be_root():
        pytest.skip(
            "a private SLURM test cluster needs root or passwordless sudo "
            "(slurmd starts jobs as their owner)"
        )
    folder = tmp_path_factory.mktemp("slurm")
    cluster = SlurmCluster(conf=folder / "slurm.conf", dir=folder)
    start = subprocess.run(
        ["bash", str(SLURM_SCRIPTS / "start.sh"), str(folder)],
        capture_output=True,
        text=True,
        timeout=180,
    )
    if start.returncode != 0:
        subprocess.run(["bash", str(SLURM_SCRIPTS / "stop.sh"), str(folder)], timeout=120)
        # start.sh's stderr already ends with the tails of the daemons' logs.
        pytest.fail(f"tests/slurm/start.sh {folder} failed:\n{start.stderr}", pytrace=False)
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("SLURM_CONF", str(cluster.conf))
        try:
            yield cluster
        finally:
            subprocess.run(["bash", str(SLURM_SCRIPTS / "stop.sh"), str(folder)], timeout=120)


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """The SLURM tests share one cluster: one xdist group, so one worker runs them all."""
    for item in items:
        if item.get_closest_marker("slurm"):
            item.add_marker(pytest.mark.xdist_group("slurm"))
