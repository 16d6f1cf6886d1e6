#!/bin/bash
# Third part: the fastest-learning decay of frames.sh (k = 3e-4, Z's log-probability) against pre-trained,
# 3 seeds each, at equal decisions (20 iterations, evaluation every 5), today's code for both.
cd "$(git rev-parse --show-toplevel)"
out=docs/results/runs/moving_2026-12-02/fast_e
while pgrep -f "fast_e/frames2.sh" > /dev/null; do sleep 10; done
run() {
  name=$1; shift
  echo "$(date -u +%H:%M:%S) start $name load $(cut -d' ' -f1 /proc/loadavg)" >> $out/frames.log
  .venv/bin/python -m agrl.train progress=false threads=1 task=uniform speed=100 eval.interval=5 \
    ppo.total_frames=655360 ppo.max_minutes=30 target_success=0.99 eval.trajectory_image=false \
    "$@" hydra.run.dir=$out/$name > $out/$name.train.log 2>&1
  grep "iter \|stopped" $out/$name/train.log | cut -c 40-200 >> $out/frames.log
}
for seed in 0 1 2; do
  run frames_pretrained_s$seed method=pretrained seed=$seed
  [ $seed = 0 ] || run frames_k3e-4_current_s$seed method=reuse method.start_from_baseline=true seed=$seed \
    method.selection_decay=3e-4 method.behaviour_log_prob=current
done
echo "$(date -u +%H:%M:%S) done" >> $out/frames.log
