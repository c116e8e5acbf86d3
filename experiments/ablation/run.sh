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
# A variant that fails to train or evaluate (its log: RUNS/NAME.log) does not stop the others: the table holds every
# variant with an evaluation, the failed ones are listed after it, and the script then exits 1.
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

one() {  # train then evaluate one variant: NAME|DATA|TRAIN ARGS; logs in RUNS/NAME.log, RUNS/NAME.failed if it fails
  IFS='|' read -r name data train <<< "$1"
  rm -f "$RUNS/$name.failed"
  train_variant() {
    if [ -f "$RUNS/$name/model.safetensors" ]; then echo "$name: trained already";
    elif [ -f "$RUNS/$name/checkpoints/last.pt" ]; then cerberus train --out "$RUNS/$name" --resume;
    else mapfile -d '' -t targs < <(python experiments/ablation/variants.py argv "$train")
         cerberus train "${targs[@]}" --set renderer=warp --set data.root="$data" --set train.steps="$STEPS" \
           --set train.progress=false --out "$RUNS/$name"; fi
  }
  # a training that fails is not evaluated (its last checkpoint would be scored as if it had finished)
  { train_variant && cerberus eval "$RUNS/$name"; } > "$RUNS/$name.log" 2>&1 && echo "$name: done" \
    || { echo "$name: FAILED (see $RUNS/$name.log)"; touch "$RUNS/$name.failed"; return 1; }
}
export -f one; export RUNS STEPS
# A variant that fails does not stop the others, nor the table of those that finished; the script fails at the end.
status=0
xargs -d '\n' -P "$JOBS" -I{} bash -c 'one "$@"' _ {} < "$RUNS/plan.txt" || status=1  # -d: each line as it is
# The table: one row per variant that has an evaluation, in plan.txt's order, each paired with the first
# (docs/evaluation.md, cerberus compare); a variant that failed this time is left out even with an older one.
evaluations=(); failed=()
while IFS='|' read -r name _; do
  if [ -f "$RUNS/$name.failed" ]; then failed+=("$name");
  elif [ -f "$RUNS/$name/eval/results.json" ]; then evaluations+=("$name=$RUNS/$name");
  else failed+=("$name"); fi  # neither failed nor evaluated: its job did not run to the end
done < "$RUNS/plan.txt"
first=$(head -n 1 "$RUNS/plan.txt" | cut -d'|' -f1)
if [ ${#evaluations[@]} -gt 0 ]; then
  [ "${evaluations[0]%%=*}" = "$first" ] \
    || echo "note: the first variant, $first, has no evaluation: the rows are paired with ${evaluations[0]%%=*}" >&2
  cerberus compare "${evaluations[@]}" --columns parts,depth,training | tee "$RUNS/ablation.md" || status=1
else
  echo "no variant has an evaluation: no table" >&2
fi
if [ ${#failed[@]} -gt 0 ]; then
  echo "failed, not in the table: ${failed[*]} (each one's log: $RUNS/NAME.log)" >&2
  status=1
fi
exit "$status"
