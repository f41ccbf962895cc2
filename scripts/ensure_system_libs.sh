#!/usr/bin/env bash
# Install the Debian/Ubuntu libraries that `import bpy` and `import open3d` need, when missing
# (open3d fails to import without libusb-1.0-0). See scripts/apt_ensure.sh for who may install.
set -euo pipefail
if ! command -v dpkg-query >/dev/null 2>&1; then
  # Elsewhere pip's wheels may still find what they need: say what to check, do not stop.
  echo "ensure_system_libs: not Debian/Ubuntu; make sure X11, libGL, libEGL and libusb are installed" >&2
  exit 0
fi
exec bash "$(dirname "$0")/apt_ensure.sh" ensure_system_libs \
  libx11-6 libxrender1 libxfixes3 libxi6 libxkbcommon0 libxext6 libxcb1 libsm6 libice6 \
  libgl1 libegl1 libudev1 libusb-1.0-0
