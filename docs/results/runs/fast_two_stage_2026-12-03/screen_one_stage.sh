#!/bin/bash
# One stage instead of two for make train-fast? Its two stages take 34 + 80 iterations. Here the fast recipe
# trains from scratch at the larger switch cost directly (`k0.3`: reward.switch_cost=0.3; `k0.2`: 0.2), position
# term alone, 100 iterations, a 1000-episode evaluation every 10 iterations for the curve (success and instructions
# against iterations). Seeds 0-2; two one-thread runs at a time (success, instructions and iterations are the
# measure, not seconds).
#   bash docs/results/runs/fast_two_stage_2026-12-03/screen_one_stage.sh
#   bash docs/results/runs/fast_two_stage_2026-12-03/screen_one_stage_eval.sh   # 10 000-episode evaluations
#   python -m agrl.report runs docs/results/runs/fast_two_stage_2026-12-03/one_stage
cd "$(git rev-parse --show-toplevel)"
export OMP_NUM_THREADS=1
out=docs/results/runs/fast_two_stage_2026-12-03/one_stage
mkdir -p $out
log=$out/screen.log
echo "$(date -u +%FT%H:%M:%S) screen starts at commit $(git rev-parse --short HEAD)" >> $log
run() {  # name overrides...
  local name=$1; shift
  echo "$(date -u +%H:%M:%S) start $name load $(cut -d' ' -f1-3 /proc/loadavg)" >> $log
  .venv/bin/python -m agrl.train "$@" threads=1 progress=false hydra.run.dir=$out/$name > /dev/null 2>&1 \
    || echo "FAILED $name" >> $log
  echo "$(date -u +%H:%M:%S) done  $name: $(tail -n 1 $out/$name/train.log | cut -c1-200)" >> $log
}
one_stage="+experiment=fast reward.use_continuous_action=false target_success=0 ppo.max_minutes=0 \
  ppo.total_frames=3276800 eval.interval=10 eval.min_train_success=0"
for seed in 0 1 2; do
  run k0.3_s$seed $one_stage reward.switch_cost=0.3 seed=$seed &
  run k0.2_s$seed $one_stage reward.switch_cost=0.2 seed=$seed &
  wait
done
# The checkpoints stay for screen_one_stage_eval.sh, which deletes them. (When this screen ran on 2026-12-03 this
# line deleted them here; hence that script's KEPT copies and its `again` runs.)
echo "$(date -u +%H:%M:%S) screen done" >> $log
