#!/bin/bash
# After wallclock_r500.sh, the same protocol at uniform 10 m/s, 2 seeds: a check that the faster decay does not
# hurt where reuse worked in the 3-seed sweep. Policy reuse (Algorithm 1, Z from scratch), default decay against the faster one.
cd "$(git rev-parse --show-toplevel)"
out=docs/results/runs/moving_2026-12-02/fast_e
while pgrep -f "fast_e/wallclock_r500.sh" > /dev/null; do sleep 10; done
fast="method.selection_decay=3e-4 method.behaviour_log_prob=current"
for seed in 0 1; do
  for variant in reuse_default reuse_fast; do
    extra="method=reuse"; [ $variant = reuse_fast ] && extra="method=reuse $fast"
    name=u10_${variant}_s$seed
    echo "$(date -u +%H:%M:%S) start $name load $(cut -d' ' -f1 /proc/loadavg) commit $(git rev-parse --short HEAD)" >> $out/wallclock.log
    .venv/bin/python -m agrl.train progress=false task=uniform speed=10 seed=$seed ppo.max_minutes=3 \
      target_success=0.99 eval.interval_seconds=15 $extra hydra.run.dir=$out/$name > $out/$name.train.log 2>&1
    tail -n 1 $out/$name/train.log | cut -c 40-300 >> $out/wallclock.log
  done
done
echo "$(date -u +%H:%M:%S) done" >> $out/wallclock.log
