#!/usr/bin/env bash
# The 100 m/s race of 2026-12-03: pre-training against reuse + B (Z from B's weights) with e starting at 0.5 and at
# 0.2 instead of 1 (method.initial_selection_factor; e = 0 is pre-training exactly), 3 seeds, methods interleaved per
# seed, one run at a time on the otherwise idle VM. Output: sitting.log and one folder per run.
set -u
out=docs/results/runs/initial_e_2026-12-03
log=$out/sitting.log
py=.venv/bin/python
stamp() { echo "## $(date -u +%FT%TZ) commit $(git rev-parse --short HEAD) load $(cut -d' ' -f1-3 /proc/loadavg): $*" >> "$log"; }
race() {  # race <name> <seed> <overrides...>
  local name=$1 seed=$2; shift 2
  stamp "$name seed $seed"
  $py -m agrl.train progress=false task=uniform speed=100 "seed=$seed" ppo.max_minutes=4 target_success=0.99 \
      eval.interval_seconds=15 "$@" "hydra.run.dir=$out/${name}_s$seed" >> "$log" 2>&1
}
for seed in 0 1 2; do
  race pretrained "$seed" method=pretrained
  race reuseB_e0.5 "$seed" method=reuse method.start_from_baseline=true method.initial_selection_factor=0.5
  race reuseB_e0.2 "$seed" method=reuse method.start_from_baseline=true method.initial_selection_factor=0.2
done
stamp done
