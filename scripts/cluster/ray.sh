#!/usr/bin/env bash
# A real local Ray cluster (one head node on 127.0.0.1) for tests/test_distributed.py
# and for trying the Ray launcher by hand (docs/SCALING.md).
#
#   scripts/cluster/ray.sh up       install ray + hydra-ray-launcher into $VENV if missing,
#                                   start a head node unless one answers; prints its address
#   scripts/cluster/ray.sh down     stop it (`ray stop`)
#   scripts/cluster/ray.sh status   `ray status`
#   scripts/cluster/ray.sh install  only the packages
#
#   VENV            the virtualenv (default: .venv of this repository)
#   RAY_PORT        the head's GCS port (default 6379)
#   RAY_NUM_CPUS    CPUs the head offers (default: the usable cores)
#   RAY_SPEC        the ray requirement (default ray==2.60.0)
#
# Needs no root. hydra-ray-launcher 1.2.2 pins cloudpickle<3 (for its AWS launcher),
# while joblib 1.6 needs cloudpickle>=3: installing it with its dependencies would
# downgrade cloudpickle under hydra-joblib-launcher. So it is installed with --no-deps,
# beside ray itself: the local `ray` launcher uses only ray and hydra-core.
# Idempotent: `up` with everything in place returns in a few seconds.
set -euo pipefail
cd "$(dirname "$0")/../.."
VENV=${VENV:-.venv}
PORT=${RAY_PORT:-6379}
NUM_CPUS=${RAY_NUM_CPUS:-$(env -u OMP_NUM_THREADS nproc)}
RAY_SPEC=${RAY_SPEC:-ray==2.60.0}
LAUNCHER_SPEC=hydra-ray-launcher==1.2.2
PY=$VENV/bin/python
ADDRESS=127.0.0.1:$PORT
# Keep Ray on the loopback address: by default it swaps 127.0.0.1 for the address of the
# machine's outward interface. The variable is named for Windows/macOS, where loopback is
# the default; on Linux it does the same. A driver connecting to this head sets it too
# (tests/test_distributed.py, docs/SCALING.md).
export RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER=0

say() { echo "ray.sh: $*" >&2; }
die() { say "$*"; exit 1; }

installed() {
  "$PY" - <<'EOF' 2>/dev/null
import importlib.metadata as md
import ray  # noqa: F401
import hydra_plugins.hydra_ray_launcher.ray_launcher  # noqa: F401
assert md.version("hydra-ray-launcher") == "1.2.2"
EOF
}

install_packages() {
  [ -x "$PY" ] || die "no $PY: run \`make setup\` first"
  installed && return 0
  say "installing $RAY_SPEC and $LAUNCHER_SPEC into $VENV (pip) ..."
  "$PY" -m pip install -q "$RAY_SPEC" 2>&1 | grep -v "^WARNING: Location" >&2 || true
  "$PY" -m pip install -q --no-deps "$LAUNCHER_SPEC" 2>&1 | grep -v "^WARNING: Location" >&2 || true
  installed || die "pip install $RAY_SPEC $LAUNCHER_SPEC failed"
}

running() {  # `ray status` exits 0 while the head is still starting: look for a node
  local out
  # Nothing listening: say so at once (`ray status` would retry for half a minute).
  (exec 3<>"/dev/tcp/127.0.0.1/$PORT") 2>/dev/null || return 1
  out=$("$VENV/bin/ray" status --address="$ADDRESS" 2>/dev/null) || return 1
  grep -qE "^ +[0-9]+ node_" <<<"$out"
}

up() {
  install_packages
  if ! running; then
    say "starting a Ray head on $ADDRESS with $NUM_CPUS CPUs ..."
    # The workers inherit this environment (not the hnnbench command's): a sweep passes
    # its own variables with hydra.launcher.ray.init.runtime_env (docs/SCALING.md).
    RAY_USAGE_STATS_ENABLED=0 "$VENV/bin/ray" start --head --node-ip-address=127.0.0.1 \
      --port="$PORT" --num-cpus="$NUM_CPUS" --num-gpus=0 --include-dashboard=false \
      --object-store-memory=$((200 * 1024 * 1024)) --disable-usage-stats >/tmp/hnnbench-ray-start.log 2>&1 \
      || { tail -20 /tmp/hnnbench-ray-start.log >&2; die "ray start failed (log: /tmp/hnnbench-ray-start.log)"; }
    local i
    for ((i = 0; i < 60; i++)); do running && break; sleep 1; done
    running || die "the Ray head did not answer on $ADDRESS"
  fi
  echo "$ADDRESS"
}

case "${1:-}" in
  up) up ;;
  down) [ -x "$VENV/bin/ray" ] && "$VENV/bin/ray" stop >/dev/null 2>&1; true ;;
  status) "$VENV/bin/ray" status --address="$ADDRESS" ;;
  install) install_packages ;;
  *) echo "usage: $0 up|down|status|install" >&2; exit 2 ;;
esac
