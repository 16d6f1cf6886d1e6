#!/bin/bash
# Uniform 100 and 50 m/s with the paper's observation (equation 4, agent.observation=absolute): pre-trained and
# Algorithm 1 from the distilled baseline, 3 seeds, one run at a time on the otherwise idle machine.
# Run from the repository root: bash docs/results/runs/paper_observation_2026-12-02/sitting.sh
set -u
OUT=docs/results/runs/paper_observation_2026-12-02
B=$OUT/baseline_absolute.pt
RUNS=${RUNS:-/tmp/abs/runs}
mkdir -p "$RUNS"
echo "commit $(git rev-parse --short HEAD)" >> $OUT/sitting.log
for speed in 100 50; do
  for seed in 0 1 2; do
    for method in pretrained reuse; do
      name=u${speed}_${method}_s$seed
      echo "$(date -u +%H:%M:%S) start $name, load $(cut -d' ' -f1-3 /proc/loadavg)" >> $OUT/sitting.log
      .venv/bin/python -m agrl.train progress=false task=uniform speed=$speed seed=$seed ppo.max_minutes=5 \
          target_success=0.99 eval.interval_seconds=15 agent.observation=absolute method=$method \
          method.baseline=$B hydra.run.dir=$RUNS/$name > $RUNS/$name.log 2>&1
      echo "$(date -u +%H:%M:%S) end $name (exit $?)" >> $OUT/sitting.log
    done
  done
done
