#!/usr/bin/env bash
# Create (or reuse) the project virtualenv in .venv and install the four packages, editable, with
# the pinned dependency versions of requirements/pins.txt. Idempotent: a second run is quick.
# Usage: source scripts/setup.sh   (or bash scripts/setup.sh)
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="${CERBERUS_VENV:-$ROOT/.venv}"
PY="${PYTHON:-python3}"
if [ ! -x "$VENV/bin/python" ]; then
  echo "[setup] creating virtualenv $VENV"
  "$PY" -m venv "$VENV"
fi
PIP=("$VENV/bin/python" -m pip install --quiet --disable-pip-version-check -c "$ROOT/requirements/pins.txt")
STAMP="$VENV/.cerberus-setup-stamp"
WANT="$(cat "$ROOT/requirements/pins.txt" "$ROOT"/packages/*/pyproject.toml | sha256sum | cut -d' ' -f1)"
if [ ! -f "$STAMP" ] || [ "$(cat "$STAMP")" != "$WANT" ]; then
  echo "[setup] installing torch (CPU build) and the cerberus packages into $VENV"
  "${PIP[@]}" torch==2.13.0
  "${PIP[@]}" -e "$ROOT/packages/cerberus-core[all]" -e "$ROOT/packages/cerberus-render-torch" \
      -e "$ROOT/packages/cerberus-render-warp" -e "$ROOT/packages/cerberus-metrics" pytest ruff setuptools
  echo "$WANT" > "$STAMP"
else
  echo "[setup] $VENV is up to date"
fi
