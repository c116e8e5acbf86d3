#!/usr/bin/env bash
# Set up the environment and run the main job on the embedded default:
#   generate the small human dataset (anny bodies, 64x64), reconstruct its test images with the
#   shipped pretrained human model (pictures + an interactive 3D viewer, within the first minutes),
#   then train the CPU preset, evaluate (voxel IoU, Hard Human, part quality), and write pictures and
#   the results table.
# Usage: bash scripts/main.sh [--quick] [OUT]     (default OUT: out/main)
#   --quick  tiny dataset and a few training steps: checks the whole pipeline in under two minutes.
# Every step resumes: re-running continues an interrupted dataset or training run.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
DATA_SIZE=small TRAIN_PRESET=cpu
if [ "${1:-}" = "--quick" ]; then DATA_SIZE=tiny TRAIN_PRESET=tiny; shift; fi
OUT="${1:-out/main}"
bash "$ROOT/scripts/setup.sh"
cd "$ROOT"
export PATH="${CERBERUS_VENV:-$ROOT/.venv}/bin:$PATH"
step() { echo; echo "== [main $(date +%H:%M:%S)] $*"; }

step "renderer backends"
cerberus renderers
step "demo scene with every backend -> $OUT/demo"
cerberus demo --out "$OUT/demo"
step "human dataset (size $DATA_SIZE) -> $OUT/data"
cerberus data generate --dataset human --size "$DATA_SIZE" --out "$OUT/data"
cerberus data show "$OUT/data" --out "$OUT/data_contact_sheet.png"
step "the shipped human model on the test images, no training -> $OUT/pretrained (open pictures/index.html)"
cerberus models
cerberus eval human --data "$OUT/data" --out "$OUT/pretrained" --no-part-quality --figure-images 6
step "training (preset $TRAIN_PRESET) -> $OUT/run"
RESUME=()
[ -f "$OUT/run/checkpoints/last.pt" ] && RESUME=(--resume)
# train.progress: the tiny preset keeps its bar off for the tests; here every training shows its progress
cerberus train --preset "$TRAIN_PRESET" --set "data.root=$OUT/data" --set train.progress=true --out "$OUT/run" "${RESUME[@]}"
step "evaluation -> $OUT/eval"
cerberus eval "$OUT/run" --out "$OUT/eval"
step "done"
echo "pretrained: $OUT/pretrained/pictures/index.html (3D viewer), $OUT/pretrained/table2.png, $OUT/pretrained/results.md"
echo "pictures:  $OUT/demo, $OUT/data_contact_sheet.png, $OUT/run (training grids, loss curve), $OUT/eval/table2.png, $OUT/eval/pictures"
echo "results:   $OUT/eval/results.md, $OUT/eval/results.json"
