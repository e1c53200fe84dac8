#!/usr/bin/env bash
# The prepared accelerator check (issue #25): bash scripts/device_check.sh [--tiny] [--out PATH]
# On one GPU: <= 8 minutes, writes results/gpu.md (experiments/device_check.py says what it measures).
# --tiny: every step on the CPU in seconds (CI), native MuJoCo standing in for MJX.
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PY:-.venv/bin/python}
[ -x "$PY" ] || PY=python3
if [[ " $* " == *" --tiny "* ]]; then
  export JAX_PLATFORMS=cpu
  exec timeout 120 "$PY" -m experiments.device_check "$@"
fi
# On an accelerator, let JAX find it (the Makefile pins the CPU for everything else).
if [ "${JAX_PLATFORMS:-}" = "cpu" ]; then unset JAX_PLATFORMS; fi
export XLA_PYTHON_CLIENT_PREALLOCATE=false
exec timeout 480 "$PY" -m experiments.device_check "$@"
