#!/bin/bash
# A shorter stage 2 for make train-fast? Its 80 fine-tune iterations take as long as stage 1. 50 iterations at a
# larger cost (`k0.4`: reward.switch_cost=0.4) or a larger learning rate (`lr2e-3`: ppo.learning_rate=2e-3), from
# make train-fast's stage 1, seeds 0-2; two one-thread runs at a time (success and instructions are the measure,
# not seconds); 10 000 episodes from seeds 777 and 4242 per agent.
#   bash docs/results/runs/fast_two_stage_2026-12-03/screen_short.sh
cd "$(git rev-parse --show-toplevel)"
export OMP_NUM_THREADS=1
out=docs/results/runs/fast_two_stage_2026-12-03/screen_short
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
run s1_s0 +experiment=fast reward.use_continuous_action=false seed=0 &
run s1_s1 +experiment=fast reward.use_continuous_action=false seed=1 &
wait
run s1_s2 +experiment=fast reward.use_continuous_action=false seed=2
for seed in 0 1 2; do
  run k0.4_s$seed +experiment=switch_finetune method.baseline=$out/s1_s$seed $narrow seed=$seed \
    reward.switch_cost=0.4 ppo.total_frames=1638400 &
  run lr2e-3_s$seed +experiment=switch_finetune method.baseline=$out/s1_s$seed $narrow seed=$seed \
    ppo.learning_rate=2e-3 ppo.total_frames=1638400 &
  wait
done
evaluate() {  # name seed
  .venv/bin/python -m agrl.evaluate checkpoint=$out/$1 episodes=10000 seed=$2 trajectories=0 \
    hydra.run.dir=$out/eval_$1_$2 > /dev/null 2>&1 || echo "FAILED eval $1 $2" >> $log
  echo "$1 seed $2: $(python3 -c "import json,sys; d=json.load(open(sys.argv[1])); print({k: d[k] for k in ('success_rate', 'instructions_per_episode', 'outcomes')})" $out/eval_$1_$2/eval.json 2>&1)" >> $log
}
for name in k0.4_s0 k0.4_s1 k0.4_s2 lr2e-3_s0 lr2e-3_s1 lr2e-3_s2; do
  evaluate $name 777 &
  evaluate $name 4242 &
  wait
done
find $out -name checkpoints -type d -exec rm -r {} +; find $out -name episodes.csv -delete
echo "$(date -u +%H:%M:%S) screen done" >> $log
