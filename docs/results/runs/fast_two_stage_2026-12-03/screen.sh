#!/bin/bash
# Issue 13, item 3: a faster way to a shipped-baseline-quality agent (>= 99.8 %, <= 7 instructions)? Stage 1 =
# +experiment=fast (2 x 64 networks, compiled loss; `both`: its reward as measured, both shaping terms; `pos`: the
# position term alone, as make train's stage 1), stage 2 = +experiment=switch_finetune on the same 2 x 64 networks
# with the compiled loss (80 iterations at k = 0.3). Seeds 0-2; two one-thread runs at a time: success and
# instructions are the measure here, not seconds (the timed sitting is sitting.sh). Each stage-2 agent flies
# 10 000 episodes from seeds 777 and 4242.
#   bash docs/results/runs/fast_two_stage_2026-12-03/screen.sh
cd "$(git rev-parse --show-toplevel)"
export OMP_NUM_THREADS=1
out=docs/results/runs/fast_two_stage_2026-12-03/screen
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
narrow="agent.actor_hidden=[64,64] agent.critic_hidden=[64,64] ppo.compile_loss=true"
for seed in 0 1 2; do
  run s1_both_s$seed +experiment=fast seed=$seed &
  run s1_pos_s$seed +experiment=fast reward.use_continuous_action=false seed=$seed &
  wait
done
for seed in 0 1 2; do
  for variant in both pos; do
    run s2_${variant}_s$seed +experiment=switch_finetune method.baseline=$out/s1_${variant}_s$seed $narrow seed=$seed &
  done
  wait
done
evaluate() {  # name seed
  .venv/bin/python -m agrl.evaluate checkpoint=$out/$1 episodes=10000 seed=$2 trajectories=0 \
    hydra.run.dir=$out/eval_$1_$2 > /dev/null 2>&1 || echo "FAILED eval $1 $2" >> $log
  echo "$1 seed $2: $(python3 -c "import json,sys; d=json.load(open(sys.argv[1])); print({k: d[k] for k in ('success_rate', 'instructions_per_episode', 'outcomes')})" $out/eval_$1_$2/eval.json 2>&1)" >> $log
}
for variant in both pos; do
  for seed in 0 1 2; do
    evaluate s2_${variant}_s$seed 777 &
    evaluate s2_${variant}_s$seed 4242 &
    wait
  done
done
find $out -name checkpoints -type d -exec rm -r {} +; find $out -name episodes.csv -delete
echo "$(date -u +%H:%M:%S) screen done" >> $log
