#!/bin/bash
# After sitting.sh, the same protocol at uniform 20 m/s and on the curved destination of radius 1000 m.
cd "$(git rev-parse --show-toplevel)"
out=docs/results/runs/moving_2026-12-02/defaults_sweep
while pgrep -f "defaults_sweep/sitting.sh" > /dev/null; do sleep 5; done
for setting in "uniform speed=20" "curved radius=1000"; do
  set -- $setting
  short=$1_${2#*=}
  for seed in 0 1 2; do
    for method in scratch reuse pretrained; do
      name=${short}_${method}_s$seed
      echo "$(date -u +%H:%M:%S) start $name load $(cut -d' ' -f1 /proc/loadavg) commit $(git rev-parse --short HEAD)" >> $out/sitting.log
      .venv/bin/python -m agrl.train progress=false task=$1 $2 method=$method seed=$seed ppo.max_minutes=4 \
        target_success=0.99 eval.interval_seconds=15 hydra.run.dir=$out/$name > $out/$name.train.log 2>&1
      tail -n 1 $out/$name/train.log | cut -c 40-300 >> $out/sitting.log
    done
  done
done
echo "$(date -u +%H:%M:%S) done" >> $out/sitting.log
