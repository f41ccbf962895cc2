#!/usr/bin/env bash
# Start a private single-node SLURM whose config, state, spool, logs and pid files all live in <dir>.
#
#   eval "$(bash tests/slurm/start.sh /tmp/slurm)"   # sets SLURM_CONF for sbatch, sinfo, ...
#   bash tests/slurm/stop.sh /tmp/slurm
#
# Loopback only: the controller and the node daemon bind to 127.0.0.1. Ports: SLURM_TEST_CTLD_PORT
# and SLURM_TEST_SLURMD_PORT when set, else the first free pair from 16817/16818 upward, so it never
# clashes with a system SLURM (6817/6818) or with a second test cluster on the same machine.
# SLURM_TEST_START_TIMEOUT (seconds, default 60) bounds the wait for the node to become idle.
# The node gets the machine's CPU count (nproc) and memory (free -m). Every start is a fresh cluster:
# the old state and spool are removed (the old logs are kept as *.log.1).
# Needs root or passwordless sudo (slurmd starts jobs as their owner) and the packages of
# tests/slurm/install.sh.
# Prints only the export line on stdout; everything else goes to stderr.
set -euo pipefail
# The daemons live in sbin, which is not on a normal user's PATH on Debian.
PATH="$PATH:/usr/sbin:/sbin"

die() {
  echo "tests/slurm/start.sh: $*" >&2
  exit 1
}

[ $# -eq 1 ] || die "usage: start.sh <dir>  (a folder for slurm.conf, state, spool, logs)"
for exe in munged munge slurmctld slurmd sinfo scontrol; do
  command -v "$exe" >/dev/null 2>&1 || die "'$exe' not found; install SLURM with: bash tests/slurm/install.sh"
done
mkdir -p "$1"
dir="$(cd "$1" && pwd)"
# slurmd starts every job as the user who submitted it, so the daemons run as root.
if [ "$(id -u)" -ne 0 ]; then
  if command -v sudo >/dev/null 2>&1 && sudo -n true 2>/dev/null; then
    exec sudo -n env "SUDO_OWNER=$(id -u):$(id -g)" \
      ${SLURM_TEST_CTLD_PORT:+"SLURM_TEST_CTLD_PORT=$SLURM_TEST_CTLD_PORT"} \
      ${SLURM_TEST_SLURMD_PORT:+"SLURM_TEST_SLURMD_PORT=$SLURM_TEST_SLURMD_PORT"} \
      ${SLURM_TEST_START_TIMEOUT:+"SLURM_TEST_START_TIMEOUT=$SLURM_TEST_START_TIMEOUT"} \
      bash "$0" "$dir"
  fi
  die "needs root or passwordless sudo: slurmd starts every job as the user who submitted it"
fi
case "$dir" in
  *[[:space:]]*) die "'$dir' contains white space, which slurm.conf cannot hold; pick another folder" ;;
esac
conf="$dir/slurm.conf"
node="$(hostname -s 2>/dev/null || hostname)"
# slurmstepd listens on a unix socket <dir>/spool/<node>_<job>.<step>; such paths hold 107 bytes.
[ $((${#dir} + ${#node} + 29)) -le 107 ] \
  || die "'$dir' is too long for slurmstepd's sockets; use a shorter folder"
timeout_s="${SLURM_TEST_START_TIMEOUT:-60}"

alive() { # alive <pidfile> <command name>: the pid file names a running process of that command
  local pid
  [ -s "$1" ] || return 1
  pid="$(cat "$1")"
  [ -r "/proc/$pid/comm" ] && [ "$(cat "/proc/$pid/comm")" = "$2" ] \
    && [ "$(awk '{print $3}' "/proc/$pid/stat" 2>/dev/null)" != Z ]
}

log_tail() {
  local f
  for f in "$dir/slurmctld.log" "$dir/slurmd.log"; do
    [ -f "$f" ] && { echo "---- tail of $f" >&2; tail -n 25 "$f" >&2; }
  done
  return 0
}

node_state() { SLURM_CONF="$conf" sinfo -h -N -n "$node" -o '%T' 2>/dev/null | head -n 1; }

# Started already (by an earlier call on the same folder) and healthy: nothing to do.
if alive "$dir/slurmctld.pid" slurmctld && alive "$dir/slurmd.pid" slurmd \
  && [ "$(node_state)" = idle ]; then
  echo "export SLURM_CONF=$conf"
  exit 0
fi
# One start at a time per machine, so two test sessions never pick the same free ports. The
# daemons must not inherit the lock (fd 9), or it would be held until they exit.
exec 9>"${TMPDIR:-/tmp}/nbv-slurm-test-start.lock"
flock 9
# Half-started or stale: clear it away before starting fresh.
bash "$(dirname "$0")/stop.sh" "$dir"

# munge authenticates every message; one munged per machine serves all clusters, so reuse it.
if ! munge -n </dev/null >/dev/null 2>&1; then
  install -d -o munge -g munge -m 0755 /run/munge
  [ -s /etc/munge/munge.key ] || die "/etc/munge/munge.key missing; reinstall munge (bash tests/slurm/install.sh)"
  runuser -u munge -- munged --force 9>&- || die "munged failed to start (see /var/log/munge/munged.log)"
  for _ in $(seq 50); do
    munge -n </dev/null >/dev/null 2>&1 && break
    sleep 0.1
  done
  munge -n </dev/null >/dev/null 2>&1 || die "munged started but 'munge -n' still fails"
fi

port_busy() { (exec 3<>"/dev/tcp/127.0.0.1/$1") 2>/dev/null; }
if [ -n "${SLURM_TEST_CTLD_PORT:-}" ] || [ -n "${SLURM_TEST_SLURMD_PORT:-}" ]; then
  ctld_port="${SLURM_TEST_CTLD_PORT:-16817}"
  slurmd_port="${SLURM_TEST_SLURMD_PORT:-$((ctld_port + 1))}"
  for p in "$ctld_port" "$slurmd_port"; do
    port_busy "$p" && die "port $p (from SLURM_TEST_CTLD_PORT/SLURM_TEST_SLURMD_PORT) is in use"
  done
else
  ctld_port=16817
  while port_busy "$ctld_port" || port_busy "$((ctld_port + 1))"; do
    ctld_port=$((ctld_port + 2))
    [ "$ctld_port" -lt 16917 ] || die "no free port pair in 16817-16916; set SLURM_TEST_CTLD_PORT"
  done
  slurmd_port=$((ctld_port + 1))
fi

cpus="$(env -u OMP_NUM_THREADS -u OMP_THREAD_LIMIT nproc)" # nproc obeys both; SLURM must not
mem_mb="$(free -m | awk '/^Mem:/ {print $2}')"
rm -rf "$dir/state" "$dir/spool"
mkdir -p "$dir/state" "$dir/spool"
for f in slurmctld slurmd; do
  [ -f "$dir/$f.log" ] && mv -f "$dir/$f.log" "$dir/$f.log.1"
done

cat >"$conf" <<EOF
# Written by tests/slurm/start.sh: a private single-node cluster on loopback.
ClusterName=nbvtest
SlurmctldHost=$node(127.0.0.1)
SlurmctldPort=$ctld_port
SlurmdPort=$slurmd_port
# Bind to the addresses above (127.0.0.1), not to every interface.
CommunicationParameters=NoCtldInAddrAny,NoInAddrAny
SlurmUser=root
AuthType=auth/munge
CryptoType=crypto/munge
MpiDefault=none
# No cgroups and no systemd in containers: track processes by parent pid, bind no tasks.
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
# CPUs are the consumable resource; memory is only checked against RealMemory at submission.
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
ReturnToService=2
# Reject at submission a job that could never run here, instead of queueing it forever.
EnforcePartLimits=ALL
# sbatch --wait polls every 2 s only while MinJobAge/2 <= 2 s; the default (300) stretches its
# polls to 2, 8, 32 s, so a 3 s job would return after 10 s. Finished jobs are forgotten sooner.
MinJobAge=5
# Trust the node line below even if the hardware probe disagrees (never drain the only node).
SlurmdParameters=config_overrides
MailProg=/bin/true
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$dir/slurmctld.pid
SlurmdPidFile=$dir/slurmd.pid
SlurmctldLogFile=$dir/slurmctld.log
SlurmdLogFile=$dir/slurmd.log
SlurmctldDebug=info
SlurmdDebug=info
NodeName=$node NodeAddr=127.0.0.1 NodeHostname=$node CPUs=$cpus RealMemory=$mem_mb State=UNKNOWN
PartitionName=debug Nodes=$node Default=YES MaxTime=INFINITE State=UP
EOF

fail() { # fail <message>: show the logs, stop what did start, and exit 1
  log_tail
  bash "$(dirname "$0")/stop.sh" "$dir" || true
  die "$1"
}
slurmctld -f "$conf" -c 9>&- || fail "slurmctld failed to start (config $conf)"
slurmd -f "$conf" -N "$node" 9>&- || fail "slurmd failed to start (config $conf)"

deadline=$((SECONDS + timeout_s))
state=""
while [ "$SECONDS" -lt "$deadline" ]; do
  state="$(node_state)"
  [ "$state" = idle ] && break
  sleep 0.5
done
[ "$state" = idle ] \
  || fail "node '$node' not idle after ${timeout_s}s (state: '${state:-no answer}'); config $conf"
# When started through sudo, leave the folder to its owner (pytest deletes old temporary folders).
[ -z "${SUDO_OWNER:-}" ] || chown -R "$SUDO_OWNER" "$dir"
echo "export SLURM_CONF=$conf"
