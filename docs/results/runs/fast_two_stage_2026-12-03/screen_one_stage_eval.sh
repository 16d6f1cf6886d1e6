#!/bin/bash
# The one-stage screen's final agents on 10 000 episodes from seeds 777 and 4242 (two one-thread evaluations at a
# time). screen_one_stage.sh deleted the checkpoints when it finished: seeds 0 and 1 were copied aside before that
# and are put back here (from $KEPT), seed 2 is trained again (one thread: the same agent; `again` runs, whose own
# final 1000-episode evaluation must equal the screen's).
#   bash docs/results/runs/fast_two_stage_2026-12-03/screen_one_stage_eval.sh   # after screen_one_stage.sh
#   (on 2026-12-03: KEPT=<the copies' folder> bash ...; without KEPT the screen's own checkpoints are used)
cd "$(git rev-parse --show-toplevel)"
export OMP_NUM_THREADS=1
out=docs/results/runs/fast_two_stage_2026-12-03/one_stage
log=$out/screen.log
echo "$(date -u +%FT%H:%M:%S) evaluation starts at commit $(git rev-parse --short HEAD)" >> $log
one_stage="+experiment=fast reward.use_continuous_action=false target_success=0 ppo.max_minutes=0 \
  ppo.total_frames=3276800 eval.interval=10 eval.min_train_success=0"
for k in 0.2 0.3; do
  .venv/bin/python -m agrl.train $one_stage reward.switch_cost=$k seed=2 threads=1 progress=false \
    hydra.run.dir=$out/k${k}_s2_again > /dev/null 2>&1 || echo "FAILED k${k}_s2_again" >> $log &
done
wait
for k in 0.2 0.3; do
  echo "k${k}_s2 again: same final evaluation as the screen's: $(python3 -c "import json,sys; a=json.load(open(sys.argv[1])); b=json.load(open(sys.argv[2])); print(all(a[x] == b[x] for x in ('success_rate', 'instructions_per_episode', 'iterations', 'outcomes')))" $out/k${k}_s2/eval/eval.json $out/k${k}_s2_again/eval/eval.json)" >> $log
  if [ -n "$KEPT" ]; then for seed in 0 1; do cp -r $KEPT/k${k}_s$seed/checkpoints $out/k${k}_s$seed/; done; fi
done
evaluate() {  # run checkpoint-run seed
  .venv/bin/python -m agrl.evaluate checkpoint=$out/$2 episodes=10000 seed=$3 trajectories=0 \
    hydra.run.dir=$out/eval_$1_$3 > /dev/null 2>&1 || echo "FAILED eval $1 $3" >> $log
  echo "$1 seed $3: $(python3 -c "import json,sys; d=json.load(open(sys.argv[1])); print({k: d[k] for k in ('success_rate', 'instructions_per_episode', 'outcomes')})" $out/eval_$1_$3/eval.json 2>&1)" >> $log
}
for k in 0.2 0.3; do
  for seed in 0 1 2; do
    run=k${k}_s$seed; source=$run; [ $seed = 2 ] && source=${run}_again
    evaluate $run $source 777 &
    evaluate $run $source 4242 &
    wait
  done
done
rm -rf $out/*/checkpoints $out/*/eval/episodes.csv $out/eval_*/episodes.csv $out/*_again/tensorboard
echo "$(date -u +%H:%M:%S) evaluation done" >> $log
