#!/usr/bin/env bash
# Rebuild Table 1 of docs/results.md: generate the small human and animal datasets, train Cerberus,
# Free Cerberus and the NMRr baseline on each (CPU schedule, Warp renderer), evaluate each run on its
# test split, and write the table. Run from the repository root inside the project's environment
# (scripts/setup.sh). Each training uses one thread; JOBS (default 2) trainings run side by side.
#   bash experiments/table1/run.sh                      # about 1.5 hours on the 2-core machine (see docs/results.md)
#   JOBS=1 RUNS=runs/table1 bash experiments/table1/run.sh
set -euo pipefail
cd "$(dirname "$0")/../.."
JOBS=${JOBS:-2}
RUNS=${RUNS:-runs/table1}
mkdir -p "$RUNS"
cerberus data generate --dataset human --size small --out data/human --renderer warp
cerberus data generate --dataset animal --size small --out data/animal --renderer warp

one() {  # train then evaluate one experiment; logs in RUNS/NAME.log
  local name=$1 runs=$2
  local data=data/${name%%_*}
  {
    if [ -f "$runs/$name/model.safetensors" ]; then echo "$name: trained already";
    elif [ -f "$runs/$name/checkpoints/last.pt" ]; then cerberus train --out "$runs/$name" --resume;
    else cerberus train --config "experiments/table1/$name.yaml" --out "$runs/$name"; fi
    cerberus eval "$runs/$name" --data "$data"
  } > "$runs/$name.log" 2>&1 && echo "$name: done" || { echo "$name: FAILED (see $runs/$name.log)"; return 1; }
}
export -f one
printf '%s\n' human_cerberus human_nmrr human_free_cerberus animal_cerberus animal_free_cerberus animal_nmrr \
  | xargs -P "$JOBS" -I{} bash -c 'one {} '"$RUNS"
python experiments/table1/table.py "$RUNS" > "$RUNS/table1.md"
for ds in human animal; do  # the paper's Table 2 layout: input, baselines, ours, parts, turntable
  cerberus eval "$RUNS/${ds}_cerberus" --data "data/$ds" --out "$RUNS/${ds}_figure" --no-part-quality \
    --baseline NMRr="$RUNS/${ds}_nmrr" --baseline "Free Cerberus=$RUNS/${ds}_free_cerberus" > "$RUNS/${ds}_figure.log" 2>&1
done
cat "$RUNS/table1.md"
echo "figures: $RUNS/human_figure/table2.png $RUNS/animal_figure/table2.png"
