#!/bin/bash
# sitting2.sh's `long` recipe met both of issue 13's item-2 targets on seed 1 (99.83 / 99.88 % at 6.86 / 6.87
# instructions on seeds 777 / 4242) and came near on seeds 0 and 2. Seed 1 was picked by those two evaluation
# sets, so: retrain the three seeds (one thread each, as before: the runs are deterministic for a given thread
# count; seed 1's evaluation on 777 must come out the same), then evaluate all three on a third set of 10 000
# episodes, seed 20261203, not looked at before the pick.
#   bash docs/results/runs/switch_finetune/position_2026-12-03/sitting3.sh
cd "$(git rev-parse --show-toplevel)"
export OMP_NUM_THREADS=1
out=docs/results/runs/switch_finetune/position_2026-12-03
log=$out/sitting3.log
echo "$(date -u +%FT%H:%M:%S) sitting starts at commit $(git rev-parse --short HEAD)" >> $log
train() {  # name seed
  echo "$(date -u +%H:%M:%S) start $1 load $(cut -d' ' -f1-3 /proc/loadavg)" >> $log
  # Edited after the sitting so that it reruns today (conf/experiment/switch_finetune.yaml changed with its results):
  # the stage-1 agent is named (it was the shipped file then) and the experiment of then is spelled out.
  .venv/bin/python -m agrl.train +experiment=switch_finetune reward.use_continuous_action=false \
    method.baseline=docs/results/baseline_2026-12-03/fixed_baseline.pt \
    ppo.minibatch_size=512 ppo.learning_rate=5e-4 ppo.total_frames=1310720 \
    ppo.minibatch_size=4096 ppo.learning_rate=1e-3 ppo.total_frames=2621440 seed=$2 threads=1 progress=false \
    hydra.run.dir=$out/$1 > /dev/null 2>&1 || echo "FAILED $1" >> $log
  echo "$(date -u +%H:%M:%S) done  $1: $(tail -n 1 $out/$1/train.log | cut -c1-160)" >> $log
}
evaluate() {  # name seed
  .venv/bin/python -m agrl.evaluate checkpoint=$out/$1 episodes=10000 seed=$2 trajectories=0 \
    hydra.run.dir=$out/eval_$1_$2 > /dev/null 2>&1 || echo "FAILED eval $1 $2" >> $log
  echo "$1 seed $2: $(python3 -c "import json,sys; d=json.load(open(sys.argv[1])); print({k: d[k] for k in ('success_rate', 'instructions_per_episode', 'outcomes')})" $out/eval_$1_$2/eval.json 2>&1)" >> $log
}
train again_long_s1 1 & train again_long_s0 0 & wait
train again_long_s2 2 & evaluate again_long_s1 777 & wait
evaluate again_long_s0 20261203 & evaluate again_long_s1 20261203 & wait
evaluate again_long_s2 20261203 & evaluate again_long_s0 777 & wait
echo "$(date -u +%H:%M:%S) sitting done (checkpoints kept for now)" >> $log
