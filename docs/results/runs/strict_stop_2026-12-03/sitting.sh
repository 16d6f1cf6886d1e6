#!/usr/bin/env bash
# `make train`'s recipe with +experiment=fast's stop (every 2 iterations, 1000 episodes, 0.998, no evaluation before
# 95 % training success on the full box), seeds 0-2, one command at a time on the otherwise idle VM, 2 threads;
# then each agent on 10 000 episodes from seeds 777 and 4242 (untimed). Output: sitting.log, s<seed>/.
set -u
out=docs/results/runs/strict_stop_2026-12-03
log=$out/sitting.log
py=.venv/bin/python
stamp() { echo "## $(date -u +%FT%TZ) commit $(git rev-parse --short HEAD) load $(cut -d' ' -f1-3 /proc/loadavg): $*" >> "$log"; }
stop=(target_success=0.998 eval.interval=2 eval.periodic_episodes=1000 eval.trajectory_image=false eval.min_train_success=0.95)
for seed in 0 1 2; do
  stamp "train defaults with the strict stop, seed $seed"
  $py -m agrl.train progress=false seed=$seed "${stop[@]}" "hydra.run.dir=$out/s$seed" >> "$log" 2>&1
done
for seed in 0 1 2; do
  for eval_seed in 777 4242; do
    stamp "evaluate s$seed on seed $eval_seed"
    $py -m agrl.evaluate "checkpoint=$out/s$seed" episodes=10000 seed=$eval_seed trajectories=0 \
        "output_dir=$out/s$seed/eval_$eval_seed" "hydra.run.dir=$out/s$seed/eval_$eval_seed" >> "$log" 2>&1
  done
done
stamp done
