#!/bin/bash
# One run at a time on the otherwise idle machine: uniform 100 m/s, 3-minute budget, evaluation every 15 s of
# training (the protocol of ../run.sh). Pre-trained against reuse with a faster decay of e (k = 3e-4, Z's own
# log-probability for relabelled rows), Z from scratch (Algorithm 1) and Z from B's weights.
cd "$(git rev-parse --show-toplevel)"
out=docs/results/runs/moving_2026-12-02/fast_e
while pgrep -f "fast_e/frames3.sh" > /dev/null; do sleep 10; done
fast="method.selection_decay=3e-4 method.behaviour_log_prob=current"
for seed in 0 1 2; do
  for variant in pretrained reuse_fast reuseB_fast; do
    case $variant in
      pretrained) extra="method=pretrained" ;;
      reuse_fast) extra="method=reuse $fast" ;;
      reuseB_fast) extra="method=reuse method.start_from_baseline=true $fast" ;;
    esac
    name=wall_${variant}_s$seed
    echo "$(date -u +%H:%M:%S) start $name load $(cut -d' ' -f1 /proc/loadavg) commit $(git rev-parse --short HEAD)" >> $out/wallclock.log
    .venv/bin/python -m agrl.train progress=false task=uniform speed=100 seed=$seed ppo.max_minutes=3 \
      target_success=0.99 eval.interval_seconds=15 $extra hydra.run.dir=$out/$name > $out/$name.train.log 2>&1
    tail -n 1 $out/$name/train.log | cut -c 40-300 >> $out/wallclock.log
  done
done
echo "$(date -u +%H:%M:%S) done" >> $out/wallclock.log
