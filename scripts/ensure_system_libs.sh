#!/usr/bin/env bash
# Install the Debian/Ubuntu libraries that `import bpy` and `import open3d` need, when missing.
# Root installs directly, a sudoer through sudo; anyone else gets the exact command to run.
set -euo pipefail

packages=(libx11-6 libxrender1 libxfixes3 libxi6 libxkbcommon0 libxext6 libxcb1 libsm6 libice6
          libgl1 libegl1 libudev1 libusb-1.0-0 "$@")

if ! command -v dpkg-query >/dev/null 2>&1; then
  echo "ensure_system_libs: not a Debian/Ubuntu system; make sure these libraries are installed:" >&2
  echo "  ${packages[*]}" >&2
  exit 0
fi

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done
[ ${#missing[@]} -eq 0 ] && exit 0

cmd="apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends ${missing[*]}"
echo "ensure_system_libs: installing ${missing[*]}" >&2
if [ "$(id -u)" -eq 0 ]; then
  bash -c "$cmd"
elif command -v sudo >/dev/null 2>&1 && sudo -n true 2>/dev/null; then
  sudo bash -c "$cmd"
else
  echo "ensure_system_libs: missing system libraries and no root or sudo rights. Run as root:" >&2
  echo "  $cmd" >&2
  exit 1
fi
