#!/usr/bin/env bash
# Set up the environment and run the main job on the embedded default.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bash "$ROOT/scripts/setup.sh"
cd "$ROOT"
export PATH="${CERBERUS_VENV:-$ROOT/.venv}/bin:$PATH"
OUT="${1:-out}"
cerberus renderers
cerberus demo --out "$OUT/demo"
echo "[main] pictures in $OUT/demo"
