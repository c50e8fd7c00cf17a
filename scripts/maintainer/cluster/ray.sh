#!/usr/bin/env bash
# A real local Ray cluster (one head node on 127.0.0.1) for tests/e2e/test_distributed.py
# and for trying the Ray launcher by hand (docs/SCALING.md).
#
#   scripts/maintainer/cluster/ray.sh up       install ray + hydra-ray-launcher if missing, start a head
#                                   node unless one answers; prints its address
#   scripts/maintainer/cluster/ray.sh down     stop it (`ray stop`)
#   scripts/maintainer/cluster/ray.sh status   `ray status`
#   scripts/maintainer/cluster/ray.sh install  only the packages
#   scripts/maintainer/cluster/ray.sh site     print the directory to put on PYTHONPATH
#
#   VENV            the virtualenv whose python runs everything (default: .venv here)
#   RAY_SITE        where ray and the plugin are installed (default $VENV/ray-site)
#   RAY_PORT        the head's GCS port (default 6379)
#   RAY_NUM_CPUS    CPUs the head offers (default: the usable cores)
#   RAY_SPEC        the ray requirement (default ray==2.60.0)
#
# Needs no root. ray and hydra-ray-launcher go to a directory of their own ($RAY_SITE,
# `pip install --target`), used through PYTHONPATH by the head (so by its workers) and
# by an `hnnbench` command that sweeps on it; .venv itself is left as it was:
# - hydra-ray-launcher 1.2.2 pins cloudpickle<3 (for its AWS launcher), while joblib 1.6
#   needs cloudpickle>=3: it is installed without its dependencies (the local `ray`
#   launcher uses only ray and hydra-core), and of ray's own requirements only those that
#   .venv does not meet are added (msgpack, protobuf);
# - with the plugin in .venv, `hydra/launcher=ray` would stop being "not installed" for
#   every other command and test run from it.
# Idempotent: `up` with everything in place returns in a few seconds.
set -euo pipefail
cd "$(dirname "$0")/../../.."
VENV=${VENV:-.venv}
PY=$VENV/bin/python
SITE=$(realpath -m "${RAY_SITE:-$VENV/ray-site}")
export PYTHONPATH="$SITE${PYTHONPATH:+:$PYTHONPATH}"
PORT=${RAY_PORT:-6379}
NUM_CPUS=${RAY_NUM_CPUS:-$(env -u OMP_NUM_THREADS nproc)}
RAY_SPEC=${RAY_SPEC:-ray==2.60.0}
LAUNCHER_SPEC=hydra-ray-launcher==1.2.2
ADDRESS=127.0.0.1:$PORT
# Keep Ray on the loopback address: by default it swaps 127.0.0.1 for the address of the
# machine's outward interface. The variable is named for Windows/macOS, where loopback is
# the default; on Linux it does the same. A driver connecting to this head sets it too
# (tests/e2e/test_distributed.py, docs/SCALING.md).
export RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER=0 RAY_USAGE_STATS_ENABLED=0

say() { echo "ray.sh: $*" >&2; }
die() { say "$*"; exit 1; }
ray_cli() { "$PY" -m ray.scripts.scripts "$@"; }

installed() {
  "$PY" -c '
import importlib.metadata as md
import ray
import hydra_plugins.hydra_ray_launcher.ray_launcher
assert md.version("hydra-ray-launcher") == "1.2.2"
' 2>/dev/null
}

# ray's requirements (no extras) that the environment does not meet, one per line.
UNMET='
import importlib.metadata as md
from packaging.requirements import Requirement
for text in md.requires("ray") or []:
    req = Requirement(text)
    if req.marker and not req.marker.evaluate({"extra": ""}):
        continue
    try:
        ok = req.specifier.contains(md.version(req.name), prereleases=True)
    except md.PackageNotFoundError:
        ok = False
    if not ok:
        print(f"{req.name}{req.specifier}")
'

pip_target() {
  "$PY" -m pip install -q --no-deps --upgrade --target "$SITE" "$@" 2>&1 \
    | { grep -v "^WARNING: Location\|^WARNING: Target directory" || true; } >&2
}

install_packages() {
  [ -x "$PY" ] || die "no $PY: run \`make setup\` first"
  installed && return 0
  say "installing $RAY_SPEC and $LAUNCHER_SPEC into $SITE (pip --target) ..."
  pip_target "$RAY_SPEC" "$LAUNCHER_SPEC"
  local unmet
  unmet=$("$PY" -c "$UNMET")
  # shellcheck disable=SC2086
  [ -z "$unmet" ] || pip_target $unmet
  installed || die "pip install --target $SITE $RAY_SPEC $LAUNCHER_SPEC failed"
}

running() {  # `ray status` exits 0 while the head is still starting: look for a node
  local out
  # Nothing listening: say so at once (`ray status` would retry for half a minute).
  (exec 3<>"/dev/tcp/127.0.0.1/$PORT") 2>/dev/null || return 1
  out=$(ray_cli status --address="$ADDRESS" 2>/dev/null) || return 1
  grep -qE "^ +[0-9]+ node_" <<<"$out"
}

up() {
  install_packages
  if ! running; then
    say "starting a Ray head on $ADDRESS with $NUM_CPUS CPUs ..."
    # The workers inherit this environment (not the hnnbench command's): a sweep passes
    # its own variables with hydra.launcher.ray.init.runtime_env (docs/SCALING.md).
    ray_cli start --head --node-ip-address=127.0.0.1 --port="$PORT" \
      --num-cpus="$NUM_CPUS" --num-gpus=0 --include-dashboard=false \
      --object-store-memory=$((200 * 1024 * 1024)) --disable-usage-stats \
      >/tmp/hnnbench-ray-start.log 2>&1 \
      || { tail -20 /tmp/hnnbench-ray-start.log >&2; die "ray start failed (log: /tmp/hnnbench-ray-start.log)"; }
    local i
    for ((i = 0; i < 60; i++)); do running && break; sleep 1; done
    running || die "the Ray head did not answer on $ADDRESS"
  fi
  echo "$ADDRESS"
}

case "${1:-}" in
  up) up ;;
  down) if [ -d "$SITE/ray" ]; then ray_cli stop >/dev/null 2>&1 || true; fi ;;
  status) ray_cli status --address="$ADDRESS" ;;
  install) install_packages ;;
  site) echo "$SITE" ;;
  *) echo "usage: $0 up|down|status|install|site" >&2; exit 2 ;;
esac
