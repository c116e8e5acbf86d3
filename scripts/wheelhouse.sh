#!/usr/bin/env bash
# Build the toolkit's four wheels into one folder (the wheelhouse) with the constraints file that keeps
# every install from it on this release:
#   dist/wheelhouse/cerberus_core-*.whl ... and dist/wheelhouse/constraints.txt
# Usage: bash scripts/wheelhouse.sh [OUT]   (default OUT: dist/wheelhouse)
# Then, in any environment (torch's CPU build first on a CPU-only machine: pip install torch==2.13.0):
#   pip install --find-links dist/wheelhouse -c dist/wheelhouse/constraints.txt cerberus-core cerberus-render-warp
# The four packages require each other at exactly one version with the local label "+toolkit", which the
# public package index cannot hold, so no sibling requirement can resolve to the unrelated project named
# `cerberus-core` there; the constraints file pins the names you type yourself the same way.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
OUT="${1:-$ROOT/dist/wheelhouse}"
PY="${PYTHON:-$( [ -x "$ROOT/.venv/bin/python" ] && echo "$ROOT/.venv/bin/python" || echo python3 )}"
VERSION="$("$PY" -c 'import ast,sys; t=ast.parse(open(sys.argv[1]).read()); print(next(n.value.value for n in t.body if isinstance(n, ast.Assign) and n.targets[0].id == "VERSION"))' "$ROOT/packages/cerberus-core/src/cerberus_core/release.py")"
mkdir -p "$OUT"
rm -f "$OUT"/cerberus_*.whl
# Each wheel is built from a fresh copy of its package without setuptools' build/ and *.egg-info folders:
# built in place, a module deleted from src/ would still ship from a stale build/lib of an earlier build.
STAGE="$(mktemp -d)"
trap 'rm -rf "$STAGE"' EXIT
echo "[wheelhouse] building 4 wheels into $OUT; pip works quietly, up to a minute a wheel on a busy 2-core machine"
for pkg in cerberus-core cerberus-render-torch cerberus-render-warp cerberus-metrics; do
  start=$SECONDS
  echo "[wheelhouse] building $pkg $VERSION (from a clean copy) ..."
  cp -R "$ROOT/packages/$pkg" "$STAGE/$pkg"
  rm -rf "$STAGE/$pkg/build" "$STAGE/$pkg/dist"
  find "$STAGE/$pkg" \( -name "*.egg-info" -o -name "__pycache__" \) -prune -exec rm -rf {} +
  "$PY" -m pip wheel --quiet --disable-pip-version-check --no-deps --wheel-dir "$OUT" "$STAGE/$pkg"
  echo "[wheelhouse] built $pkg in $((SECONDS - start)) s"
done
{
  echo "# The Cerberus toolkit $VERSION: install its packages from this folder only (pip -c this file)."
  for pkg in cerberus-core cerberus-render-torch cerberus-render-warp cerberus-metrics; do echo "$pkg==$VERSION"; done
} > "$OUT/constraints.txt"
ls "$OUT"
