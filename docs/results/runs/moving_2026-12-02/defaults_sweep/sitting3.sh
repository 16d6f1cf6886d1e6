#!/bin/bash
# After sitting2.sh (and a CI run), the same protocol for the remaining settings of Tables 4-5: uniform 10 m/s,
# radius 2000 and 5000 m, and this project's irregular destination.
cd "$(git rev-parse --show-toplevel)"
out=docs/results/runs/moving_2026-12-02/defaults_sweep
while pgrep -f "ci/run|agrl.train|pytest" > /dev/null; do sleep 5; done
names=(uniform_10 curved_2000 curved_5000 irregular)
overrides=("task=uniform speed=10" "task=curved radius=2000" "task=curved radius=5000" "task=irregular")
for index in 0 1 2 3; do
  for seed in 0 1 2; do
    for method in scratch reuse pretrained; do
      name=${names[$index]}_${method}_s$seed
      echo "$(date -u +%H:%M:%S) start $name load $(cut -d' ' -f1 /proc/loadavg) commit $(git rev-parse --short HEAD)" >> $out/sitting.log
      .venv/bin/python -m agrl.train progress=false ${overrides[$index]} method=$method seed=$seed ppo.max_minutes=4 \
        target_success=0.99 eval.interval_seconds=15 hydra.run.dir=$out/$name > $out/$name.train.log 2>&1
      tail -n 1 $out/$name/train.log | cut -c 40-300 >> $out/sitting.log
    done
  done
done
echo "$(date -u +%H:%M:%S) done" >> $out/sitting.log
