#!/usr/bin/env bash
# Rebuild Table 1 of docs/results.md in one command: generate the human and animal datasets, train Cerberus,
# Free Cerberus and the NMRr baseline on each (the cpu recipe, Warp renderer, one thread per training),
# evaluate each on its test split, and write the table, the paired differences and the Table 2-style figures.
# Run from the repository root inside the project's environment (scripts/setup.sh).
#
#   bash experiments/table1/run.sh --scale large   # the main table: human --size large, animal --size paper,
#                                                  # 20,000 steps per model (about 100 min each, two side by side)
#   bash experiments/table1/run.sh --scale small   # the history table: --size small, 5,000 steps
#
# Every step resumes: a finished dataset or training is kept, an interrupted training continues from its last
# checkpoint (`cerberus train --out RUN --resume`), so the same command run again picks up where it stopped.
# At --scale large the human Cerberus and NMRr rows are the shipped `human` and `human-nmrr` models (trained with
# exactly this recipe and schedule: their cards); TRAIN_SHIPPED=1 trains them again instead.
# Environment: JOBS (default 2) trainings side by side; RUNS (default runs/table1_<scale>); DATA (default data).
set -euo pipefail
cd "$(dirname "$0")/../.."
SCALE=small
while [ $# -gt 0 ]; do
  case "$1" in
    --scale) [ $# -ge 2 ] || { echo "run.sh: --scale needs a value: small or large" >&2; exit 2; }
             SCALE=$2; shift 2 ;;
    --scale=*) SCALE=${1#--scale=}; shift ;;
    -h|--help) sed -n '2,15p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "run.sh: unknown argument '$1' (use --scale small|large)" >&2; exit 2 ;;
  esac
done
case "$SCALE" in
  small) HUMAN_SIZE=small; ANIMAL_SIZE=small; STEPS=5000; KEEP=0 ;;
  large) HUMAN_SIZE=large; ANIMAL_SIZE=paper; STEPS=20000; KEEP=5000 ;;
  *) echo "run.sh: --scale must be small or large, not '$SCALE'" >&2; exit 2 ;;
esac
JOBS=${JOBS:-2}
RUNS=${RUNS:-runs/table1_$SCALE}
DATA=${DATA:-data}
export RUNS STEPS KEEP SCALE
export HUMAN_DATA="$DATA/human_$HUMAN_SIZE" ANIMAL_DATA="$DATA/animal_$ANIMAL_SIZE"
mkdir -p "$RUNS"
cerberus data generate --dataset human --size "$HUMAN_SIZE" --out "$HUMAN_DATA" --renderer warp
cerberus data generate --dataset animal --size "$ANIMAL_SIZE" --out "$ANIMAL_DATA" --renderer warp

shipped() {  # the shipped model standing for a row at --scale large, or nothing
  [ "$SCALE" = large ] && [ "${TRAIN_SHIPPED:-0}" != 1 ] || return 0
  case "$1" in human_cerberus) echo human ;; human_nmrr) echo human-nmrr ;; esac
}
model() {  # what `cerberus eval` takes for a row: a shipped name or the run folder
  local s; s=$(shipped "$1"); echo "${s:-$RUNS/$1}"
}
one() {  # train (or resume) then evaluate one row; logs in RUNS/NAME.log
  local name=$1 data
  case "$name" in human_*) data=$HUMAN_DATA ;; *) data=$ANIMAL_DATA ;; esac
  {
    if [ -n "$(shipped "$name")" ]; then echo "$name: the shipped $(shipped "$name") model";
    elif [ -f "$RUNS/$name/model.safetensors" ]; then echo "$name: trained already";
    elif [ -f "$RUNS/$name/checkpoints/last.pt" ]; then cerberus train --out "$RUNS/$name" --resume;
    else cerberus train --config "experiments/table1/$name.yaml" --out "$RUNS/$name" --set "data.root=$data" \
           --set "train.steps=$STEPS" --set "train.keep_every=$KEEP" --set threads=1; fi
    [ -f "$RUNS/$name/eval/results.json" ] || cerberus eval "$(model "$name")" --data "$data" --out "$RUNS/$name/eval"
  } > "$RUNS/$name.log" 2>&1 && echo "$name: done" || { echo "$name: FAILED (see $RUNS/$name.log)"; return 1; }
}
export -f one shipped model
printf '%s\n' human_free_cerberus animal_cerberus animal_nmrr animal_free_cerberus human_cerberus human_nmrr \
  | xargs -P "$JOBS" -I{} bash -c 'one {}'
python experiments/table1/table.py "$RUNS" > "$RUNS/table1.md"
for ds in human animal; do  # the paper's Table 2 layout: input, baselines, ours, parts, turn view
  data=$HUMAN_DATA; [ "$ds" = animal ] && data=$ANIMAL_DATA
  cerberus eval "$(model "${ds}_cerberus")" --data "$data" --out "$RUNS/${ds}_figure" --no-part-quality \
    --baseline NMRr="$(model "${ds}_nmrr")" --baseline "Free Cerberus=$(model "${ds}_free_cerberus")" \
    > "$RUNS/${ds}_figure.log" 2>&1
done
cat "$RUNS/table1.md"
echo "figures: $RUNS/human_figure/table2.png $RUNS/animal_figure/table2.png"
