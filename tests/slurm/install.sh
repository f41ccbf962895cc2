#!/usr/bin/env bash
# Install the Debian packages of a single-node SLURM (controller, node daemon, clients, munge) when
# missing. Idempotent and quiet: prints nothing when everything is already installed.
# Root installs directly, a sudoer through `sudo -n`; anyone else gets the exact command and exit 1.
set -euo pipefail

packages=(slurmctld slurmd slurm-client munge)

if ! command -v dpkg-query >/dev/null 2>&1; then
  echo "tests/slurm/install.sh: not a Debian/Ubuntu system; install these SLURM 22.05+ parts by hand:" >&2
  echo "  ${packages[*]}" >&2
  exit 1
fi

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done
[ ${#missing[@]} -eq 0 ] && exit 0

# The daemons are started by tests/slurm/start.sh with a private config, never as system services.
cmd="apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends ${missing[*]}"
echo "tests/slurm/install.sh: installing ${missing[*]}" >&2
log="$(mktemp)"
trap 'rm -f "$log"' EXIT
if [ "$(id -u)" -eq 0 ]; then
  runner=(bash -c)
elif command -v sudo >/dev/null 2>&1 && sudo -n true 2>/dev/null; then
  runner=(sudo -n bash -c)
else
  echo "tests/slurm/install.sh: SLURM is missing and there are no root or sudo rights. Run as root:" >&2
  echo "  $cmd" >&2
  exit 1
fi
# apt's progress is noise on success; show it only when the install fails.
if ! "${runner[@]}" "$cmd" >"$log" 2>&1; then
  cat "$log" >&2
  echo "tests/slurm/install.sh: install failed: $cmd" >&2
  exit 1
fi
