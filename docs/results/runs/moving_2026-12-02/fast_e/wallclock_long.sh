#!/bin/bash
# Algorithm 1 at uniform 100 m/s with the new defaults (k = 3e-4, Z's log-probability) and a 6-minute budget:
# when does it reach 95 %? One run at a time on the otherwise idle machine, 3 seeds.
cd "$(git rev-parse --show-toplevel)"
out=docs/results/runs/moving_2026-12-02/fast_e
for seed in 0 1 2; do
  name=long_reuse_s$seed
  echo "$(date -u +%H:%M:%S) start $name load $(cut -d' ' -f1 /proc/loadavg) commit $(git rev-parse --short HEAD)" >> $out/wallclock.log
  .venv/bin/python -m agrl.train progress=false task=uniform speed=100 method=reuse seed=$seed ppo.max_minutes=6 \
    target_success=0.99 eval.interval_seconds=15 hydra.run.dir=$out/$name > $out/$name.train.log 2>&1
  tail -n 1 $out/$name/train.log | cut -c 40-300 >> $out/wallclock.log
done
echo "$(date -u +%H:%M:%S) done" >> $out/wallclock.log
