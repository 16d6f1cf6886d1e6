#!/bin/bash
# Second part of frames.sh: a faster decay, and the paper's full loop over t_n (every decision a candidate).
cd "$(git rev-parse --show-toplevel)"
out=docs/results/runs/moving_2026-12-02/fast_e
while pgrep -f "fast_e/frames.sh" > /dev/null; do sleep 10; done
run() {
  name=$1; shift
  echo "$(date -u +%H:%M:%S) start $name load $(cut -d' ' -f1 /proc/loadavg)" >> $out/frames.log
  .venv/bin/python -m agrl.train progress=false threads=1 task=uniform speed=100 eval.interval=5 \
    ppo.total_frames=655360 ppo.max_minutes=30 target_success=0.99 eval.trajectory_image=false \
    method=reuse method.start_from_baseline=true seed=0 "$@" hydra.run.dir=$out/$name > $out/$name.train.log 2>&1
  grep "iter \|stopped" $out/$name/train.log | cut -c 40-200 >> $out/frames.log
}
run frames_k1e-3_current method.selection_decay=1e-3 method.behaviour_log_prob=current
run frames_k3e-4_current_full method.selection_decay=3e-4 method.behaviour_log_prob=current method.max_candidates=200
echo "$(date -u +%H:%M:%S) done" >> $out/frames.log
