#!/bin/bash
# Equal-decision ablations of the selection factor's decay k (reuse + B, uniform 100 m/s, seed 0, 20 iterations,
# evaluation every 5): the same protocol as runs/moving_2026-12-01/frames/. Frame counts do not depend on the load.
cd "$(git rev-parse --show-toplevel)"
out=docs/results/runs/moving_2026-12-02/fast_e
run() {
  name=$1; shift
  echo "$(date -u +%H:%M:%S) start $name load $(cut -d' ' -f1 /proc/loadavg)" >> $out/frames.log
  .venv/bin/python -m agrl.train progress=false threads=1 task=uniform speed=100 eval.interval=5 \
    ppo.total_frames=655360 ppo.max_minutes=20 target_success=0.99 eval.trajectory_image=false \
    method=reuse method.start_from_baseline=true seed=0 "$@" hydra.run.dir=$out/$name > $out/$name.train.log 2>&1
  grep "iter \|stopped" $out/$name/train.log | cut -c 40-200 >> $out/frames.log
}
run frames_k1e-4_current method.selection_decay=1e-4 method.behaviour_log_prob=current
run frames_k3e-4_current method.selection_decay=3e-4 method.behaviour_log_prob=current
run frames_k1e-4_baseline method.selection_decay=1e-4
echo "$(date -u +%H:%M:%S) done" >> $out/frames.log
