#!/usr/bin/env bash
# Set up the environment and run the whole test suite (unit, conformance, end-to-end).
# Extra arguments go to pytest, e.g. `bash scripts/test.sh -m "not slow"` for the quick subset.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bash "$ROOT/scripts/setup.sh"
cd "$ROOT"
VENV="${CERBERUS_VENV:-$ROOT/.venv}"
export PATH="$VENV/bin:$PATH"   # the console scripts (cerberus, cerberus-metrics) are tested too
exec "$VENV/bin/python" -m pytest "$@"
