#!/usr/bin/env bash
# Install each of the toolkit's packages the way a user would, from the wheelhouse, in fresh virtualenvs
# with the public package index reachable, and run each one's smoke test (CI runs this; docs: README,
# "Installing with pip"). Checks, one venv each:
#   metrics alone        IoU of two boxes (no torch installed)
#   torch backend alone  `cerberus renderers` lists it and `cerberus demo` renders with it
#   warp backend alone   the same
#   core[animal]+torch   a tiny animal dataset (pymeshlab comes with the extra)
#   core[human]+torch    a tiny human dataset (anny comes with the extra)
#   core + warp          the card's pair: `cerberus reconstruct --model human IMAGE`
# and, in every venv, that no distribution named cerberus-* other than this release's was installed; and that
# installing a backend without the wheelhouse fails to resolve instead of taking the unrelated `cerberus-core`
# from the public index.
# Usage: bash scripts/install_check.sh [WORKDIR]   (default: a temporary folder, removed at the end)
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
WORK="${1:-$(mktemp -d)}"
[ -n "${1:-}" ] || trap 'rm -rf "$WORK"' EXIT
PY="${PYTHON:-python3}"
W="$WORK/wheelhouse"
PIP_QUIET=(--quiet --disable-pip-version-check)
STEP="building the wheelhouse"
fail() { echo "[install-check] FAIL ($STEP): $*" >&2; exit 1; }
# Any other command that fails stops the check with the step and the command, never silently.
trap 'echo "[install-check] FAIL ($STEP): \`$BASH_COMMAND\` exited $? (line $LINENO)" >&2' ERR

pip_in() {  # pip_in VENV ARGS...: pip install, its own error shown (the last lines of its output) if it fails
  local venv="$1"; shift
  local log="$WORK/pip-$(basename "$venv").log"
  "$venv/bin/pip" install "${PIP_QUIET[@]}" "$@" >"$log" 2>&1 \
    || fail "pip install $* in $venv failed: $(grep -v '^ *$' "$log" | tail -5 | tr '\n' ' ')"
}
fresh() {  # fresh NAME [torch]: a new venv at $WORK/NAME, with torch's CPU build when asked
  "$PY" -m venv "$WORK/$1"
  if [ "${2:-}" = torch ]; then pip_in "$WORK/$1" torch==2.13.0; fi
}
install() {  # install NAME SPEC...: from the wheelhouse, with the index reachable for third-party packages
  local venv="$WORK/$1"; shift
  pip_in "$venv" --find-links "$W" -c "$W/constraints.txt" "$@"
  "$venv/bin/python" - "$VERSION" <<'PY' || fail "a cerberus-* distribution not of this release in $venv"
import sys
from importlib import metadata
ours = {"cerberus-core", "cerberus-render-torch", "cerberus-render-warp", "cerberus-metrics"}
for dist in metadata.distributions():
    name = dist.metadata["Name"].lower().replace("_", "-")
    if name.startswith("cerberus") and (name not in ours or dist.version != sys.argv[1]):
        sys.exit(f"{name} {dist.version}")
PY
}
step() { STEP="$*"; echo "[install-check] $*"; }

bash "$ROOT/scripts/wheelhouse.sh" "$W" >/dev/null
VERSION="$(grep -v '^#' "$W/constraints.txt" | head -1 | cut -d= -f3)"

step "a backend installed without the wheelhouse does not resolve to the public index's cerberus-core"
fresh nowheel torch
if "$WORK/nowheel/bin/pip" install "${PIP_QUIET[@]}" "$ROOT/packages/cerberus-render-warp" >"$WORK/nowheel.log" 2>&1; then
  fail "cerberus-render-warp installed without the wheelhouse: $(grep -i cerberus "$WORK/nowheel.log" | head -3)"
fi
grep -q "No matching distribution found for cerberus-core==$VERSION" "$WORK/nowheel.log" || fail "unexpected: $(tail -3 "$WORK/nowheel.log")"
"$WORK/nowheel/bin/python" -c 'import importlib.util, sys; sys.exit(importlib.util.find_spec("cerberus_core") is not None)' \
  || fail "a cerberus_core module was installed"

step "cerberus-metrics alone"
fresh metrics
install metrics cerberus-metrics
"$WORK/metrics/bin/python" - <<'PY'
import importlib.util
import trimesh
from cerberus_metrics import voxel_iou
assert importlib.util.find_spec("torch") is None, "cerberus-metrics pulled in torch"
a = trimesh.creation.box((0.4, 0.4, 0.4))
b = trimesh.creation.box((0.4, 0.4, 0.4)); b.apply_translation((0.2, 0, 0))
iou = voxel_iou((a.vertices, a.faces), (b.vertices, b.faces), protocol="gt_bbox")
assert 0.2 < iou < 0.45, iou
print(f"[install-check] metrics: IoU of two half-overlapping boxes {iou:.3f}")
PY

for backend in torch warp; do
  step "cerberus-render-$backend alone"
  fresh "$backend" torch
  install "$backend" "cerberus-render-$backend"
  "$WORK/$backend/bin/cerberus" renderers | grep -E "^  $backend .* ok$" >/dev/null || fail "cerberus renderers does not list $backend"
  "$WORK/$backend/bin/cerberus" demo --out "$WORK/demo_$backend" >/dev/null
  [ -s "$WORK/demo_$backend/demo_$backend.png" ] || fail "no demo picture from $backend"
done

for kind in animal human; do
  step "cerberus-core[$kind] with the torch backend: a tiny $kind dataset"
  fresh "core_$kind" torch
  install "core_$kind" "cerberus-core[$kind]" cerberus-render-torch
  "$WORK/core_$kind/bin/cerberus" data generate --dataset "$kind" --size tiny --out "$WORK/data_$kind" >/dev/null 2>&1 \
    || fail "data generate --dataset $kind: $("$WORK/core_$kind/bin/cerberus" data generate --dataset "$kind" --size tiny --out "$WORK/data_$kind" 2>&1 | tail -1)"
  [ -f "$WORK/data_$kind/manifest.json" ] || fail "no $kind dataset written"
done

step "the card's pair, cerberus-core and cerberus-render-warp: reconstruct with the shipped human model"
fresh pair torch
install pair cerberus-core cerberus-render-warp
"$WORK/pair/bin/python" - "$WORK/person.png" <<'PY'
import sys
import numpy as np
from PIL import Image
img = np.zeros((64, 64, 3), np.uint8); img[12:56, 26:38] = 150; img[6:14, 28:36] = 170  # a grey figure on black
Image.fromarray(img).save(sys.argv[1])
PY
"$WORK/pair/bin/cerberus" reconstruct --model human "$WORK/person.png" --out "$WORK/rec" >/dev/null
[ -s "$WORK/rec/person.obj" ] || fail "reconstruct wrote no mesh"
step "all install checks passed ($VERSION)"
