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
  # pip runs quietly: say before each step what it fetches and about how long it takes, and after, how long it took.
  START=$SECONDS
  echo "[setup] step 1/2: installing torch 2.13.0 (CPU build, a large download) into $VENV; a first install takes a few" \
       "minutes (downloading and unpacking), quiet until it ends"
  "${PIP[@]}" torch==2.13.0
  echo "[setup] step 1/2 done in $((SECONDS - START)) s"
  START=$SECONDS
  echo "[setup] step 2/2: installing the four cerberus packages (editable) and their dependencies (Warp, anny," \
       "pymeshlab, ...); a first install takes a few minutes, quiet until it ends"
  "${PIP[@]}" -e "$ROOT/packages/cerberus-core[all]" -e "$ROOT/packages/cerberus-render-torch" \
      -e "$ROOT/packages/cerberus-render-warp" -e "$ROOT/packages/cerberus-metrics" pytest ruff setuptools
  echo "[setup] step 2/2 done in $((SECONDS - START)) s; $VENV is ready"
  echo "$WANT" > "$STAMP"
else
  echo "[setup] $VENV is up to date"
fi
