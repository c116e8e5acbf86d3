#!/usr/bin/env bash
# The ablation table of docs/results.md: every change of the default recipe alone against the paper-faithful
# baseline, on the small human data, in short runs (STEPS, default 3000), then all of them together.
# Variants are the rows of experiments/ablation/variants.txt (NAME | data arguments | training arguments).
# Run from the repository root inside the project's environment (scripts/setup.sh). Each training uses one
# thread; JOBS (default 2) run side by side. Datasets go to DATA (default data/ablation), runs to RUNS.
#   bash experiments/ablation/run.sh                  # about 2 hours on the 2-core machine
#   STEPS=1000 RUNS=runs/ablation_quick bash experiments/ablation/run.sh
# VARIANTS names another variants file: experiments/ablation/beyond.txt holds the changes tried on top of the
# default recipe (docs/results.md, "Beyond the default recipe"), experiments/ablation/depth.txt the depth changes
# of issue 24 (docs/results.md, "Depth the second view can see"):
#   VARIANTS=experiments/ablation/beyond.txt STEPS=5000 RUNS=runs/beyond bash experiments/ablation/run.sh
# experiments/ablation/limbs.txt holds issue 30's changes toward parts on the limbs (docs/training.md, "Beyond the
# paper: sending parts to the limbs"):
#   VARIANTS=experiments/ablation/limbs.txt STEPS=3000 RUNS=runs/limbs bash experiments/ablation/run.sh
# A DATA column "@PATH" uses an existing dataset instead of generating one. Rows are read without a shell
# (variants.py): a NAME is [A-Za-z0-9_.-]+ (no '..'), arguments are split as words and nothing in them is run.
set -euo pipefail
cd "$(dirname "$0")/../.."
JOBS=${JOBS:-2}; STEPS=${STEPS:-3000}
RUNS=${RUNS:-runs/ablation}; DATA=${DATA:-data/ablation}
mkdir -p "$RUNS" "$DATA"
VARIANTS=${VARIANTS:-experiments/ablation/variants.txt}

# Rows are read by variants.py (names checked, arguments split as words: nothing is expanded or run).
python experiments/ablation/variants.py rows "$VARIANTS" > "$RUNS/rows.txt"

# One dataset per distinct data-argument string (variants that share data share the folder).
declare -A folder
while IFS='|' read -r name data train; do
  key=$(printf '%s\n' "$data" | sha1sum | cut -c1-8)
  if [ "${data:0:1}" = "@" ]; then  # @PATH: an existing dataset (e.g. @data/human_large)
    folder[$key]="${data:1}"
    [ -f "${data:1}/manifest.json" ] || { echo "$name: no dataset at ${data:1} (cerberus data generate ... --out ${data:1})" >&2; exit 1; }
  elif [ -z "${folder[$key]:-}" ]; then
    folder[$key]="$DATA/$name"
    mapfile -d '' -t dargs < <(python experiments/ablation/variants.py argv "$data")
    [ -f "$DATA/$name/manifest.json" ] && grep -q '"complete": true' "$DATA/$name/manifest.json" \
      || cerberus data generate --dataset human "${dargs[@]}" --renderer warp --out "$DATA/$name" --quiet
  fi
  echo "$name|${folder[$key]}|$train"
done < "$RUNS/rows.txt" > "$RUNS/plan.txt"

one() {  # train then evaluate one variant: NAME|DATA|TRAIN ARGS; logs in RUNS/NAME.log
  IFS='|' read -r name data train <<< "$1"
  {
    if [ -f "$RUNS/$name/model.safetensors" ]; then echo "$name: trained already";
    elif [ -f "$RUNS/$name/checkpoints/last.pt" ]; then cerberus train --out "$RUNS/$name" --resume;
    else mapfile -d '' -t targs < <(python experiments/ablation/variants.py argv "$train")
         cerberus train "${targs[@]}" --set renderer=warp --set data.root="$data" --set train.steps="$STEPS" \
           --set train.progress=false --out "$RUNS/$name"; fi
    cerberus eval "$RUNS/$name"
  } > "$RUNS/$name.log" 2>&1 && echo "$name: done" || { echo "$name: FAILED (see $RUNS/$name.log)"; return 1; }
}
export -f one; export RUNS STEPS
xargs -d '\n' -P "$JOBS" -I{} bash -c 'one "$@"' _ {} < "$RUNS/plan.txt"  # -d: each line as it is, no quoting
# The table: one row per variant in plan.txt's order, each paired with the first (docs/evaluation.md, cerberus compare).
evaluations=()
while IFS='|' read -r name _; do evaluations+=("$name=$RUNS/$name"); done < "$RUNS/plan.txt"
cerberus compare "${evaluations[@]}" --columns parts,depth,training | tee "$RUNS/ablation.md"
