"""What some tests need from the machine: whether CI runs them, and the Blender binary."""

from __future__ import annotations

import os

import pytest

#: The Blender binary the binary tests run (Debian 12's package; NBV_TEST_BLENDER names another).
BINARY = os.environ.get("NBV_TEST_BLENDER", "/usr/bin/blender")


def in_ci() -> bool:
    """True when the CI variable is set to anything but an empty string, 0, false or no."""
    return os.environ.get("CI", "").strip().lower() not in ("", "0", "false", "no")


def require_binary() -> str:
    """The Blender binary under test; fails in CI when it is missing, skips elsewhere."""
    if os.access(BINARY, os.X_OK):
        return BINARY
    message = f"no Blender binary at {BINARY}; install it with `bash scripts/ensure_blender.sh`"
    if in_ci():
        pytest.fail(message + " (.ci/run should have)", pytrace=False)
    pytest.skip(message)
