#!/usr/bin/env bash
# usage: apt_ensure.sh NAME PACKAGE...
# Install the Debian/Ubuntu packages that are missing; quiet when all are there. Root installs
# directly, a sudoer through `sudo -n`; anyone else gets the exact apt-get command and exit 1.
# NAME prefixes the messages (the caller's name).
set -euo pipefail

name="$1"
shift
packages=("$@")

if ! command -v dpkg-query >/dev/null 2>&1; then
  echo "$name: not a Debian/Ubuntu system; install these packages by hand: ${packages[*]}" >&2
  exit 1
fi

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done
[ ${#missing[@]} -eq 0 ] && exit 0

cmd="apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends ${missing[*]}"
echo "$name: installing ${missing[*]}" >&2
if [ "$(id -u)" -eq 0 ]; then
  runner=(bash -c)
elif command -v sudo >/dev/null 2>&1 && sudo -n true 2>/dev/null; then
  runner=(sudo -n bash -c)
else
  echo "$name: missing ${missing[*]} and no root or sudo rights. Run as root:" >&2
  echo "  $cmd" >&2
  exit 1
fi
log="$(mktemp)"
trap 'rm -f "$log"' EXIT
# apt's progress is noise on success; show it only when the install fails.
if ! "${runner[@]}" "$cmd" >"$log" 2>&1; then
  cat "$log" >&2
  echo "$name: install failed: $cmd" >&2
  exit 1
fi
