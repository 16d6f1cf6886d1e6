#!/bin/bash
# Uniform 50 m/s with today's defaults (relative observation, the shipped baseline of 2026-12-01, Algorithm 1 with
# k = 3e-4 and Z's log-probability): scratch, pre-trained and policy reuse, 3 seeds, one run at a time on the idle
# VM, methods interleaved; 4-minute budget, evaluation every 15 s of training, stop at 99 %.
cd "$(git rev-parse --show-toplevel)"
out=docs/results/runs/moving_2026-12-02/defaults_sweep
while pgrep -f "agrl.train" > /dev/null; do sleep 5; done   # wait for the machine to be idle
for seed in 0 1 2; do
  for method in scratch reuse pretrained; do
    name=u50_${method}_s$seed
    echo "$(date -u +%H:%M:%S) start $name load $(cut -d' ' -f1 /proc/loadavg) commit $(git rev-parse --short HEAD)" >> $out/sitting.log
    .venv/bin/python -m agrl.train progress=false task=uniform speed=50 method=$method seed=$seed ppo.max_minutes=4 \
      target_success=0.99 eval.interval_seconds=15 hydra.run.dir=$out/$name > $out/$name.train.log 2>&1
    tail -n 1 $out/$name/train.log | cut -c 40-300 >> $out/sitting.log
  done
done
echo "$(date -u +%H:%M:%S) done" >> $out/sitting.log
