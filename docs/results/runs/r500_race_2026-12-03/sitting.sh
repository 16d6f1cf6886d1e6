#!/usr/bin/env bash
# The radius-500 m race of 2026-12-03, run from the repository root, one run at a time on the otherwise idle VM:
# pre-training, reuse + B (Z from B's weights) and Algorithm 1 (Z from scratch), 3 seeds, methods interleaved per
# seed, today's defaults and the shipped baseline. Output: sitting.log and one folder per run.
set -u
out=docs/results/runs/r500_race_2026-12-03
log=$out/sitting.log
py=.venv/bin/python
stamp() { echo "## $(date -u +%FT%TZ) commit $(git rev-parse --short HEAD) load $(cut -d' ' -f1-3 /proc/loadavg): $*" >> "$log"; }
race() {  # race <name> <seed> <overrides...>
  local name=$1 seed=$2; shift 2
  stamp "$name seed $seed"
  $py -m agrl.train progress=false task=curved radius=500 "seed=$seed" ppo.max_minutes=4 target_success=0.99 \
      eval.interval_seconds=15 "$@" "hydra.run.dir=$out/${name}_s$seed" >> "$log" 2>&1
}
for seed in 0 1 2; do
  race pretrained "$seed" method=pretrained
  race reuseB "$seed" method=reuse method.start_from_baseline=true
  race reuse "$seed" method=reuse
done
stamp done
