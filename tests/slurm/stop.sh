#!/usr/bin/env bash
# Stop the cluster that tests/slurm/start.sh started in <dir>: cancel its jobs, then stop slurmd and
# slurmctld by their pid files and wait for them to exit. munged stays (other clusters may share it).
# Safe to call when nothing runs. SLURM_TEST_STOP_TIMEOUT (seconds, default 20) bounds each wait
# before SIGKILL.
set -euo pipefail

[ $# -eq 1 ] || { echo "usage: stop.sh <dir>" >&2; exit 1; }
dir="$1"
timeout_s="${SLURM_TEST_STOP_TIMEOUT:-20}"
# start.sh runs the daemons as root (through sudo when needed), so stopping them needs it too.
if [ "$(id -u)" -ne 0 ] && ls "$dir"/slurmctld.pid "$dir"/slurmd.pid >/dev/null 2>&1; then
  if command -v sudo >/dev/null 2>&1 && sudo -n true 2>/dev/null; then
    exec sudo -n env ${SLURM_TEST_STOP_TIMEOUT:+"SLURM_TEST_STOP_TIMEOUT=$SLURM_TEST_STOP_TIMEOUT"} \
      bash "$0" "$dir"
  fi
fi

pid_of() { # pid_of <pidfile> <command name>: the pid, if the file names a running process of it
  local pid
  [ -s "$1" ] || return 1
  pid="$(cat "$1")"
  [ -r "/proc/$pid/comm" ] && [ "$(cat "/proc/$pid/comm")" = "$2" ] && echo "$pid"
}

running() { # running <pid>: the process exists and is not a zombie waiting to be reaped
  [ -r "/proc/$1/stat" ] && [ "$(awk '{print $3}' "/proc/$1/stat" 2>/dev/null)" != Z ]
}

# Jobs left by a failed test would otherwise outlive slurmd as orphaned slurmstepd processes.
if pid_of "$dir/slurmctld.pid" slurmctld >/dev/null && [ -f "$dir/slurm.conf" ]; then
  for _ in $(seq 20); do
    jobs="$(SLURM_CONF="$dir/slurm.conf" timeout 5 squeue -h -o %A 2>/dev/null | sort -u)" || break
    [ -n "$jobs" ] || break
    # shellcheck disable=SC2086 # one job id per word
    SLURM_CONF="$dir/slurm.conf" timeout 10 scancel $jobs >/dev/null 2>&1 || true
    sleep 0.5
  done
fi

for daemon in slurmd slurmctld; do
  pid="$(pid_of "$dir/$daemon.pid" "$daemon")" || continue
  kill -TERM "$pid" 2>/dev/null || true
  for _ in $(seq $((timeout_s * 10))); do
    running "$pid" || break
    sleep 0.1
  done
  if running "$pid"; then
    echo "tests/slurm/stop.sh: $daemon (pid $pid) ignored SIGTERM for ${timeout_s}s; killing it" >&2
    kill -KILL "$pid" 2>/dev/null || true
  fi
  rm -f "$dir/$daemon.pid"
done
