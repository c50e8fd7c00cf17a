#!/usr/bin/env bash
# A real one-node Slurm cluster on this machine, for tests/e2e/test_distributed.py and for
# trying the submitit_slurm launcher by hand (docs/SCALING.md).
#
#   scripts/maintainer/cluster/slurm.sh up       install what is missing, write the config, start
#                                     what is not running, wait until the node is idle
#   scripts/maintainer/cluster/slurm.sh down     stop the daemons this script started (pid files)
#   scripts/maintainer/cluster/slurm.sh status   print the daemons' state and `sinfo`
#   scripts/maintainer/cluster/slurm.sh install  only the Debian packages
#
# Needs root and apt-get (Debian/Ubuntu). Works in a container without systemd: every
# daemon is started directly, and the config uses no cgroups (proctrack/linuxproc,
# task/affinity). Idempotent: `up` on a running cluster returns in about a second.
#
# What runs: munged (authentication), MariaDB + slurmdbd (accounting: submitit reads job
# states with `sacct`, which needs slurmdbd), slurmctld and slurmd, all on localhost.
# One node named after this host with its real CPU count and memory (`slurmd -C`), one
# partition, $HNNBENCH_SLURM_PARTITION (default `local`).
#
# The config goes to /etc/slurm (so that sbatch, sacct and scancel need no SLURM_CONF).
# An existing slurm.conf that this script did not write is never replaced: `up` stops
# with an error instead.
set -euo pipefail

PARTITION=${HNNBENCH_SLURM_PARTITION:-local}
CLUSTER=hnnbench
MARK="# written by hnnbench scripts/maintainer/cluster/slurm.sh"
CONF_DIR=/etc/slurm
RUN=/run/slurm
LOG=/var/log/slurm
LIB=/var/lib/slurm
PACKAGES=(munge slurmctld slurmd slurm-client slurmdbd mariadb-server)

say() { echo "slurm.sh: $*" >&2; }
die() { say "$*"; exit 1; }

alive() {  # alive PIDFILE: the process named in the pid file exists
  [ -s "$1" ] && kill -0 "$(cat "$1")" 2>/dev/null
}

wait_for() {  # wait_for SECONDS WHAT COMMAND...: poll COMMAND until it succeeds
  local limit=$1 what=$2 i
  shift 2
  for ((i = 0; i < limit * 5; i++)); do
    if "$@" >/dev/null 2>&1; then return 0; fi
    sleep 0.2
  done
  die "$what not ready after ${limit}s"
}

need_root() {
  [ "$(id -u)" = 0 ] || die "needs root (installs packages and starts system daemons)"
}

install_packages() {
  need_root
  local missing=() p
  for p in "${PACKAGES[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" \
      || missing+=("$p")
  done
  [ ${#missing[@]} = 0 ] && return 0
  command -v apt-get >/dev/null || die "apt-get not found: cannot install ${missing[*]}"
  say "installing ${missing[*]} (apt-get) ..."
  # The packages' postinst would start their services: there is no init system to do it
  # in a container, and `up` starts them itself. A policy-rc.d answering 101 says so.
  local policy=/usr/sbin/policy-rc.d made_policy=""
  if [ ! -e "$policy" ]; then
    printf '#!/bin/sh\nexit 101\n' > "$policy" && chmod +x "$policy" && made_policy=1
  fi
  local rc=0
  export DEBIAN_FRONTEND=noninteractive
  # A fresh machine may have no package lists yet.
  if ! apt-get install -y -q --no-install-recommends "${missing[@]}" >/tmp/hnnbench-apt.log 2>&1
  then
    apt-get update -q >>/tmp/hnnbench-apt.log 2>&1 || true
    apt-get install -y -q --no-install-recommends "${missing[@]}" >>/tmp/hnnbench-apt.log 2>&1 \
      || rc=$?
  fi
  [ -n "$made_policy" ] && rm -f "$policy"
  if [ "$rc" != 0 ]; then
    tail -5 /tmp/hnnbench-apt.log >&2
    die "apt-get install ${missing[*]} failed (log: /tmp/hnnbench-apt.log)"
  fi
}

node_line() {  # this host as slurmd sees it: NodeName=... CPUs=... RealMemory=...
  local line
  line=$(slurmd -C | head -1)
  case "$line" in NodeName=*) ;; *) die "slurmd -C printed no node line: $line" ;; esac
  # Reach the node on the loopback address, whatever the host name resolves to.
  echo "$line NodeAddr=127.0.0.1 State=UNKNOWN"
}

write_if_changed() {  # write_if_changed FILE MODE: stdin to FILE if it differs; 0 = changed
  local file=$1 mode=$2 tmp
  tmp=$(mktemp)
  cat > "$tmp"
  if [ -f "$file" ] && cmp -s "$tmp" "$file"; then rm -f "$tmp"; return 1; fi
  install -m "$mode" "$tmp" "$file"
  rm -f "$tmp"
  return 0
}

configure() {  # writes the config; prints "changed" when a daemon must (re)read it
  local host changed=""
  host=$(hostname -s)
  mkdir -p "$CONF_DIR" "$RUN" "$LOG" "$LIB/slurmctld" "$LIB/slurmd"
  # Any copy of this script wrote it (the script has moved: the mark names its path).
  if [ -f "$CONF_DIR/slurm.conf" ] && ! grep -q "^# written by hnnbench scripts/" "$CONF_DIR/slurm.conf"; then
    die "$CONF_DIR/slurm.conf exists and was not written by this script: not replacing it"
  fi
  write_if_changed "$CONF_DIR/slurm.conf" 644 <<EOF && changed=1
$MARK
# A one-node test cluster on localhost; rewritten by \`slurm.sh up\`.
ClusterName=$CLUSTER
SlurmctldHost=$host(127.0.0.1)
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
StateSaveLocation=$LIB/slurmctld
SlurmdSpoolDir=$LIB/slurmd
SlurmctldPidFile=$RUN/slurmctld.pid
SlurmdPidFile=$RUN/slurmd.pid
SlurmctldLogFile=$LOG/slurmctld.log
SlurmdLogFile=$LOG/slurmd.log
# No cgroups: processes are tracked through /proc, and a task is bound to the CPUs it
# was given with sched_setaffinity (so cpus_per_task=1 means one core).
ProctrackType=proctrack/linuxproc
TaskPlugin=task/affinity
JobAcctGatherType=jobacct_gather/linux
# Accounting through slurmdbd: sacct (which submitit polls) needs it.
AccountingStorageType=accounting_storage/slurmdbd
AccountingStorageHost=localhost
JobCompType=jobcomp/none
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU_Memory
MpiDefault=none
ReturnToService=2
# A cancelled task gets SIGTERM, then SIGKILL 5 s later.
KillWait=5
InactiveLimit=0
MinJobAge=300
$(node_line)
PartitionName=$PARTITION Nodes=ALL Default=YES MaxTime=INFINITE State=UP
EOF
  write_if_changed "$CONF_DIR/slurmdbd.conf" 600 <<EOF && changed=1
$MARK
AuthType=auth/munge
DbdHost=localhost
SlurmUser=root
PidFile=$RUN/slurmdbd.pid
LogFile=$LOG/slurmdbd.log
# MariaDB on its local socket; root is authenticated by the socket (unix_socket).
StorageType=accounting_storage/mysql
StorageHost=localhost
StorageUser=root
StorageLoc=slurm_acct_db
EOF
  # No cgroup plugin is used; an empty cgroup.conf keeps slurmd from looking for one.
  [ -f "$CONF_DIR/cgroup.conf" ] || echo "$MARK" > "$CONF_DIR/cgroup.conf"
  [ -n "$changed" ] && echo changed
  return 0
}

start_munge() {
  local pid=/run/munge/munged.pid
  alive "$pid" && return 0
  if [ ! -s /etc/munge/munge.key ]; then
    mkdir -p /etc/munge
    if command -v mungekey >/dev/null; then mungekey --create --force; else
      dd if=/dev/urandom bs=1 count=1024 of=/etc/munge/munge.key 2>/dev/null
    fi
  fi
  chown -R munge:munge /etc/munge && chmod 700 /etc/munge && chmod 400 /etc/munge/munge.key
  mkdir -p /run/munge /var/lib/munge /var/log/munge
  chown munge:munge /run/munge /var/lib/munge /var/log/munge
  chmod 755 /run/munge
  runuser -u munge -- /usr/sbin/munged --pid-file="$pid"
  wait_for 10 munged munge -n
}

start_mariadb() {
  local pid=/run/mysqld/mysqld.pid
  if ! alive "$pid"; then
    mkdir -p /run/mysqld && chown mysql:mysql /run/mysqld
    [ -d /var/lib/mysql/mysql ] || mariadb-install-db --user=mysql >/dev/null
    setsid /usr/sbin/mariadbd --user=mysql --pid-file="$pid" --skip-networking \
      --innodb-buffer-pool-size=64M --innodb-lock-wait-timeout=900 \
      --log-error=/var/log/mysql/error.log </dev/null >/dev/null 2>&1 &
  fi
  wait_for 30 MariaDB mariadb-admin --silent ping
}

start_slurmdbd() {
  alive "$RUN/slurmdbd.pid" && return 0
  slurmdbd
  wait_for 30 slurmdbd sacctmgr -n list cluster
}

start_slurmctld() {
  alive "$RUN/slurmctld.pid" && return 0
  # Register the cluster before slurmctld connects (no-op if it is there).
  sacctmgr -i -Q add cluster "$CLUSTER" >/dev/null 2>&1 || true
  slurmctld
  wait_for 30 slurmctld scontrol ping
}

start_slurmd() {
  alive "$RUN/slurmd.pid" && return 0
  slurmd
}

node_idle() {
  sinfo -h -N -p "$PARTITION" -o '%T' | grep -qE '^(idle|mixed|allocated)'
}

stop_pidfile() {  # stop_pidfile NAME PIDFILE
  local pid i
  [ -s "$2" ] || return 0
  pid=$(cat "$2")
  if kill -0 "$pid" 2>/dev/null; then
    kill "$pid"
    for ((i = 0; i < 100; i++)); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
    kill -0 "$pid" 2>/dev/null && kill -9 "$pid" && say "$1 killed (pid $pid)"
  fi
  rm -f "$2"
}

down() {
  need_root
  stop_pidfile slurmd "$RUN/slurmd.pid"
  stop_pidfile slurmctld "$RUN/slurmctld.pid"
  stop_pidfile slurmdbd "$RUN/slurmdbd.pid"
  stop_pidfile mariadbd /run/mysqld/mysqld.pid
  stop_pidfile munged /run/munge/munged.pid
}

up() {
  need_root
  install_packages
  local changed
  changed=$(configure)
  if [ -n "$changed" ]; then  # a running daemon would keep the old config
    stop_pidfile slurmd "$RUN/slurmd.pid"
    stop_pidfile slurmctld "$RUN/slurmctld.pid"
    stop_pidfile slurmdbd "$RUN/slurmdbd.pid"
  fi
  start_munge
  start_mariadb
  start_slurmdbd
  start_slurmctld
  start_slurmd
  # A node that was down (an earlier run killed) comes back without waiting for an admin.
  if sinfo -h -N -o '%T' | grep -qE '^(down|drain)'; then
    scontrol update nodename="$(hostname -s)" state=resume >/dev/null 2>&1 || true
  fi
  wait_for 60 "the node (sinfo: $(sinfo -h -N -o '%T %E' 2>/dev/null | head -1))" node_idle
  say "up: partition $PARTITION, $(sinfo -h -N -o '%N %c CPUs %m MB %T' | head -1)"
}

status() {
  local d
  for d in "munged /run/munge/munged.pid" "mariadbd /run/mysqld/mysqld.pid" \
           "slurmdbd $RUN/slurmdbd.pid" "slurmctld $RUN/slurmctld.pid" "slurmd $RUN/slurmd.pid"; do
    set -- $d
    if alive "$2"; then echo "$1: running (pid $(cat "$2"))"; else echo "$1: stopped"; fi
  done
  command -v sinfo >/dev/null && sinfo 2>&1 || true
}

case "${1:-}" in
  up) up ;;
  down) down ;;
  status) status ;;
  install) install_packages ;;
  *) echo "usage: $0 up|down|status|install" >&2; exit 2 ;;
esac
