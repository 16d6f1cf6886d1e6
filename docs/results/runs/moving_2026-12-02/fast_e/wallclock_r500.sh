#!/bin/bash
# After wallclock.sh, the same protocol at curved radius 500 m (20 m/s): policy reuse (Algorithm 1, Z from scratch)
# with the default decay against the faster one. Pre-trained (and reuse + B, which starts from the same weights)
# is at 95 % before any training here (zero-shot, runs/moving_2026-12-01/quiet/).
cd "$(git rev-parse --show-toplevel)"
out=docs/results/runs/moving_2026-12-02/fast_e
while pgrep -f "fast_e/wallclock.sh" > /dev/null; do sleep 10; done
fast="method.selection_decay=3e-4 method.behaviour_log_prob=current"
for seed in 0 1 2; do
  for variant in reuse_default reuse_fast; do
    extra="method=reuse"; [ $variant = reuse_fast ] && extra="method=reuse $fast"
    name=r500_${variant}_s$seed
    echo "$(date -u +%H:%M:%S) start $name load $(cut -d' ' -f1 /proc/loadavg) commit $(git rev-parse --short HEAD)" >> $out/wallclock.log
    .venv/bin/python -m agrl.train progress=false task=curved radius=500 seed=$seed ppo.max_minutes=3 \
      target_success=0.99 eval.interval_seconds=15 $extra hydra.run.dir=$out/$name > $out/$name.train.log 2>&1
    tail -n 1 $out/$name/train.log | cut -c 40-300 >> $out/wallclock.log
  done
done
echo "$(date -u +%H:%M:%S) done" >> $out/wallclock.log
