#!/bin/bash
# After sitting.sh: uniform 100 and 50 m/s with the paper's observation, Algorithm 1 with the previous reuse
# defaults (e decays by 2e-5 per selected episode, B's log-probability as the behaviour log-probability);
# 3 seeds, one run at a time. Run from the repository root:
#   bash docs/results/runs/paper_observation_2026-12-02/sitting2.sh
set -u
OUT=docs/results/runs/paper_observation_2026-12-02
B=$OUT/baseline_absolute.pt
RUNS=${RUNS:-/tmp/abs/runs}
mkdir -p "$RUNS"
echo "sitting2, commit $(git rev-parse --short HEAD)" >> $OUT/sitting.log
for speed in 100 50; do
  for seed in 0 1 2; do
    name=u${speed}_reuse_slow_s$seed
    echo "$(date -u +%H:%M:%S) start $name, load $(cut -d' ' -f1-3 /proc/loadavg)" >> $OUT/sitting.log
    .venv/bin/python -m agrl.train progress=false task=uniform speed=$speed seed=$seed ppo.max_minutes=5 \
        target_success=0.99 eval.interval_seconds=15 agent.observation=absolute method=reuse method.baseline=$B \
        method.selection_decay=2e-5 method.behaviour_log_prob=baseline hydra.run.dir=$RUNS/$name > $RUNS/$name.log 2>&1
    echo "$(date -u +%H:%M:%S) end $name (exit $?)" >> $OUT/sitting.log
  done
done
