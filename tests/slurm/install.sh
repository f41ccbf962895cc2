#!/usr/bin/env bash
# Install the Debian packages of a single-node SLURM (controller, node daemon, clients, munge)
# when missing; quiet when they are there. The daemons are started by tests/slurm/start.sh with a
# private config, never as system services.
set -euo pipefail
exec bash "$(dirname "$0")/../../scripts/apt_ensure.sh" tests/slurm/install.sh \
  slurmctld slurmd slurm-client munge
