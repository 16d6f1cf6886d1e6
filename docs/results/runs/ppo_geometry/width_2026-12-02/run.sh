#!/bin/bash
# One run at a time: widths 128 (default) and 64, seeds 0-2, interleaved; then a 10 000-episode evaluation (seed 777).
cd "$(git rev-parse --show-toplevel)"
out=runs/width_2026-12-02; mkdir -p $out
for seed in 0 1 2; do
  for w in 128 64; do
    name=w${w}_s${seed}
    echo "$(date -u +%H:%M:%S) start $name load $(cut -d' ' -f1 /proc/loadavg)" >> $out/log.txt
    .venv/bin/python -m agrl.train progress=false seed=$seed "agent.actor_hidden=[$w,$w]" "agent.critic_hidden=[$w,$w]" \
      hydra.run.dir=$out/$name > $out/$name.train.log 2>&1
    tail -n 1 $out/$name.train.log >> $out/log.txt
    .venv/bin/python -m agrl.evaluate checkpoint=$out/$name episodes=10000 seed=777 trajectories=0 \
      hydra.run.dir=$out/$name/eval_seed777 > $out/$name.eval.log 2>&1
    tail -n 1 $out/$name.eval.log >> $out/log.txt
  done
done
echo "$(date -u +%H:%M:%S) done" >> $out/log.txt
