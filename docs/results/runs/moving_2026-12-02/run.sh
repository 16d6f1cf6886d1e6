#!/bin/bash
# One run at a time: policy reuse at uniform 100 m/s, Algorithm 1 as is against method.relabel_unfinished=false.
cd "$(git rev-parse --show-toplevel)"
out=${OUT:-runs/moving_2026-12-02}; mkdir -p $out
for seed in 0 1 2; do
  for variant in default unfinished_once; do
    extra=""; [ $variant = unfinished_once ] && extra="method.relabel_unfinished=false"
    name=${variant}_s$seed
    echo "$(date -u +%H:%M:%S) start $name load $(cut -d' ' -f1 /proc/loadavg)" >> $out/log.txt
    .venv/bin/python -m agrl.train progress=false task=uniform speed=100 method=reuse seed=$seed ppo.max_minutes=3 \
      target_success=0.99 eval.interval_seconds=15 $extra hydra.run.dir=$out/$name > $out/$name.train.log 2>&1
    tail -n 1 $out/$name.train.log | cut -c1-300 >> $out/log.txt
  done
done
echo "$(date -u +%H:%M:%S) done" >> $out/log.txt
