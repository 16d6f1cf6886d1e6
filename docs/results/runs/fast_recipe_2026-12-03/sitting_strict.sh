#!/usr/bin/env bash
# The second sitting of 2026-12-03: `+experiment=fast` with a stricter stop (target_success=0.998: at most 2
# failures in the 1000 periodic episodes, against 5), seeds 0-2, one command at a time on the otherwise idle VM;
# then each agent on 10 000 episodes from seeds 777 and 4242 (untimed). Output: sitting_strict.log, strict_s<seed>/.
set -u
out=docs/results/runs/fast_recipe_2026-12-03
log=$out/sitting_strict.log
py=.venv/bin/python
stamp() { echo "## $(date -u +%FT%TZ) commit $(git rev-parse --short HEAD) load $(cut -d' ' -f1-3 /proc/loadavg): $*" >> "$log"; }
for seed in 0 1 2; do
  stamp "train fast target_success=0.998 seed $seed"
  $py -m agrl.train +experiment=fast target_success=0.998 progress=false seed=$seed "hydra.run.dir=$out/strict_s$seed" >> "$log" 2>&1
done
for run in strict_s0 strict_s1 strict_s2; do
  for seed in 777 4242; do
    stamp "evaluate $run on seed $seed"
    $py -m agrl.evaluate "checkpoint=$out/$run" episodes=10000 seed=$seed trajectories=0 \
        "output_dir=$out/$run/eval_$seed" "hydra.run.dir=$out/$run/eval_$seed" >> "$log" 2>&1
  done
done
stamp done
