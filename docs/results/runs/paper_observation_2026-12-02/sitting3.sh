#!/bin/bash
# After sitting2.sh: uniform 50 m/s with the paper's observation, training from scratch (the start-box
# curriculum on, as for every scratch run); 3 seeds, one run at a time. From the repository root:
#   bash docs/results/runs/paper_observation_2026-12-02/sitting3.sh
set -u
OUT=docs/results/runs/paper_observation_2026-12-02
RUNS=${RUNS:-/tmp/abs/runs}
mkdir -p "$RUNS"
echo "sitting3, commit $(git rev-parse --short HEAD)" >> $OUT/sitting.log
for seed in 0 1 2; do
  name=u50_scratch_s$seed
  echo "$(date -u +%H:%M:%S) start $name, load $(cut -d' ' -f1-3 /proc/loadavg)" >> $OUT/sitting.log
  .venv/bin/python -m agrl.train progress=false task=uniform speed=50 seed=$seed ppo.max_minutes=5 \
      target_success=0.99 eval.interval_seconds=15 agent.observation=absolute method=scratch \
      hydra.run.dir=$RUNS/$name > $RUNS/$name.log 2>&1
  echo "$(date -u +%H:%M:%S) end $name (exit $?)" >> $OUT/sitting.log
done
