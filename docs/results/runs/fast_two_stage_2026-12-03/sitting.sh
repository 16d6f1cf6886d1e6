#!/bin/bash
# Issue 13, item 3, timed: the fast recipe's two stages against make train's, one run at a time on the idle VM,
# 2 torch threads unless named. Stage 1 = +experiment=fast with the position term alone (make train's stage-1
# reward), stage 2 = +experiment=switch_finetune with the compiled loss; `fast64`: fast.yaml's 2 x 64 networks,
# `fast128`: the shipped 2 x 128 ones. Seeds 0-2, the two interleaved; `make_train`: make train's own two commands
# (stage 1 seed 0, stage 2 seed 1 on one thread), once, after seed 0. Afterwards (untimed, two at a time) every
# final agent flies 10 000 episodes from seeds 777 and 4242.
#   bash docs/results/runs/fast_two_stage_2026-12-03/sitting.sh
#   python -m agrl.report runs docs/results/runs/fast_two_stage_2026-12-03/sitting
cd "$(git rev-parse --show-toplevel)"
out=docs/results/runs/fast_two_stage_2026-12-03/sitting
mkdir -p $out
log=$out/sitting.log
echo "$(date -u +%FT%H:%M:%S) sitting starts at commit $(git rev-parse --short HEAD)" >> $log
run() {  # name overrides...
  local name=$1; shift
  echo "$(date -u +%H:%M:%S) start $name load $(cut -d' ' -f1-3 /proc/loadavg)" >> $log
  local start=$(date +%s.%N)
  .venv/bin/python -m agrl.train "$@" progress=false hydra.run.dir=$out/$name > /dev/null 2>&1 || echo "FAILED $name" >> $log
  local end=$(date +%s.%N)
  echo "$(date -u +%H:%M:%S) done  $name: command $(python3 -c "print(round($end - $start, 1))") s; $(python3 -c "import json,sys; d=json.load(open(sys.argv[1])); print('training', d['training_wall_time_s'], 's,', d['iterations'], 'iterations,', d['success_rate'], 'success,', round(d['instructions_per_episode'], 2), 'instructions')" $out/$name/eval/eval.json 2>&1)" >> $log
}
two_stage() {  # name seed width
  local name=$1 seed=$2 width=$3
  local nets="agent.actor_hidden=[$width,$width] agent.critic_hidden=[$width,$width]"
  run ${name}_s${seed}_stage1 +experiment=fast reward.use_continuous_action=false $nets seed=$seed threads=2
  run ${name}_s${seed}_stage2 +experiment=switch_finetune method.baseline=$out/${name}_s${seed}_stage1 \
    $nets ppo.compile_loss=true seed=$seed threads=2
}
for seed in 0 1 2; do
  two_stage fast64 $seed 64
  two_stage fast128 $seed 128
  if [ $seed = 0 ]; then  # make train's two commands (Makefile), as a user runs them
    run make_train_stage1
    run make_train_stage2 +experiment=switch_finetune method.baseline=$out/make_train_stage1 seed=1 threads=1
  fi
done
echo "$(date -u +%H:%M:%S) timed runs done" >> $log
evaluate() {  # name seed
  OMP_NUM_THREADS=1 .venv/bin/python -m agrl.evaluate checkpoint=$out/$1 episodes=10000 seed=$2 trajectories=0 \
    hydra.run.dir=$out/eval_$1_$2 > /dev/null 2>&1 || echo "FAILED eval $1 $2" >> $log
  echo "$1 seed $2: $(python3 -c "import json,sys; d=json.load(open(sys.argv[1])); print({k: d[k] for k in ('success_rate', 'instructions_per_episode', 'outcomes')})" $out/eval_$1_$2/eval.json 2>&1)" >> $log
}
for name in fast64_s0 fast64_s1 fast64_s2 fast128_s0 fast128_s1 fast128_s2 make_train; do
  evaluate ${name}_stage2 777 &
  evaluate ${name}_stage2 4242 &
  wait
done
find $out -name checkpoints -type d -exec rm -r {} +; find $out -name episodes.csv -delete
echo "$(date -u +%H:%M:%S) sitting done" >> $log
