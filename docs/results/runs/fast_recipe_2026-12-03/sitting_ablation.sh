#!/usr/bin/env bash
# The third sitting of 2026-12-03: what two of `+experiment=fast`'s changes are worth, each taken out alone
# (`ppo.compile_loss=false`; `eval.min_train_success=0`, evaluations every 2 iterations from the start), seeds 0-2,
# one command at a time on the otherwise idle VM; then each agent on 10 000 episodes from seed 777 (untimed).
# Output: sitting_ablation.log, eager_s<seed>/, nowait_s<seed>/.
set -u
out=docs/results/runs/fast_recipe_2026-12-03
log=$out/sitting_ablation.log
py=.venv/bin/python
stamp() { echo "## $(date -u +%FT%TZ) commit $(git rev-parse --short HEAD) load $(cut -d' ' -f1-3 /proc/loadavg): $*" >> "$log"; }
for seed in 0 1 2; do
  stamp "train fast ppo.compile_loss=false seed $seed"
  $py -m agrl.train +experiment=fast ppo.compile_loss=false progress=false seed=$seed "hydra.run.dir=$out/eager_s$seed" >> "$log" 2>&1
  stamp "train fast eval.min_train_success=0 seed $seed"
  $py -m agrl.train +experiment=fast eval.min_train_success=0 progress=false seed=$seed "hydra.run.dir=$out/nowait_s$seed" >> "$log" 2>&1
done
for run in eager_s0 eager_s1 eager_s2; do
  stamp "evaluate $run on seed 777"
  $py -m agrl.evaluate "checkpoint=$out/$run" episodes=10000 seed=777 trajectories=0 \
      "output_dir=$out/$run/eval_777" "hydra.run.dir=$out/$run/eval_777" >> "$log" 2>&1
done
stamp done
