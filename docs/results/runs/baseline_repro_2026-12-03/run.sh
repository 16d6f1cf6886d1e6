#!/usr/bin/env bash
# `make train`'s recipe on one torch thread, a seed per call, then 10 000 episodes from seeds 777 and 4242.
# (Seed 0 was run alone; seeds 1 and 2 two at a time, so only their agents, not their wall times, are comparable.)
# Usage: run.sh <seed>
set -eu
seed=$1
out=docs/results/runs/baseline_repro_2026-12-03/make_train_threads1_s$seed
py=.venv/bin/python
OMP_NUM_THREADS=1 $py -m agrl.train threads=1 seed=$seed progress=false ppo.max_minutes=0 ppo.total_frames=4000000 \
    "hydra.run.dir=$out" > "$out.log" 2>&1
for eval_seed in 777 4242; do
  $py -m agrl.evaluate "checkpoint=$out" episodes=10000 seed=$eval_seed trajectories=0 \
      "output_dir=$out/eval_$eval_seed" "hydra.run.dir=$out/eval_$eval_seed" > /dev/null 2>&1
done
