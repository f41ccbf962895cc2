#!/usr/bin/env bash
# Install the distribution's Blender binary and the numpy of the system Python it runs, when
# missing; quiet when they are there. CI tests the dataset renderer with this binary
# (tests/test_blender_binary.py; Debian 12 packages Blender 3.4.1, the oldest supported), beside
# the bpy wheel of the venv. Without python3-numpy the binary starts but its Python cannot import
# numpy, which the renderer's preflight check reports.
set -euo pipefail
exec bash "$(dirname "$0")/apt_ensure.sh" scripts/ensure_blender.sh blender python3-numpy
