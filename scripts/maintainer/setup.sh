#!/usr/bin/env bash
# Create .venv and install hnnbench with every backend and the test tools.
# Idempotent: re-running after a change of pyproject.toml reinstalls, else does nothing.
#   TORCH_SPEC  torch requirement (default torch==2.13.0: on the project's CI machines
#               pip resolves it to the CPU build found locally; elsewhere pip picks
#               its default build). On a GPU machine set e.g. TORCH_SPEC="torch"
#               for the newest CUDA build; a change of TORCH_SPEC upgrades torch.
#   PYTHON      interpreter used to create the venv (default python3)
set -euo pipefail
cd "$(dirname "$0")/../.."
PYTHON=${PYTHON:-python3}
TORCH_SPEC=${TORCH_SPEC:-torch==2.13.0}
stamp=.venv/.hnnbench-setup
want="$(sha256sum pyproject.toml | cut -c1-16) $TORCH_SPEC"
if [ -f "$stamp" ] && [ "$(cat "$stamp")" = "$want" ]; then
  exit 0
fi
echo "setup: creating .venv and installing hnnbench[all,test] ($TORCH_SPEC) ..." >&2
[ -x .venv/bin/python ] || "$PYTHON" -m venv .venv
.venv/bin/python -m pip install -q --upgrade pip setuptools wheel
# torch first and pinned, so that no later requirement pulls a different build.
# --upgrade: a TORCH_SPEC changed on an existing .venv (e.g. "torch" after the pinned
# CPU build) replaces the installed torch instead of counting as already met.
.venv/bin/python -m pip install -q --upgrade "$TORCH_SPEC"
.venv/bin/python -m pip install -q -e ".[all,test]"
echo "$want" > "$stamp"
echo "setup: done (.venv)" >&2
