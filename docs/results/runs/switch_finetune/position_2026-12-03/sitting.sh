#!/bin/bash
# Stage 2 (fine-tune at k = 0.3) with the position term alone, from the shipped baseline of 2026-12-03 (itself
# trained with the position term alone at k = 0.1). Every earlier fine-tune kept both shaping terms and started
# from the 2026-12-01 baseline (switch_cost.md). Two recipes, seeds 0-2 each: `ft` = +experiment=switch_finetune
# as it is (40 iterations); `quiet` = minibatch 4096, learning rate 1e-3, 50 iterations ("Quieter fine-tunes").
# Success and instructions are the measure, not seconds: two one-thread runs at a time, then the weight average
# of each recipe's three seeds, then 10 000 episodes from seeds 777 and 4242 for every agent.
#   bash docs/results/runs/switch_finetune/position_2026-12-03/sitting.sh
cd "$(git rev-parse --show-toplevel)"
export OMP_NUM_THREADS=1
out=docs/results/runs/switch_finetune/position_2026-12-03
log=$out/sitting.log
echo "$(date -u +%FT%H:%M:%S) sitting starts at commit $(git rev-parse --short HEAD)" >> $log
train() {  # name seed extra-overrides...
  local name=$1 seed=$2; shift 2
  echo "$(date -u +%H:%M:%S) start $name load $(cut -d' ' -f1-3 /proc/loadavg)" >> $log
  # Edited after the sitting so that it reruns today (conf/experiment/switch_finetune.yaml changed with its results):
  # the stage-1 agent is named (it was the shipped file then) and the experiment of then is spelled out.
  .venv/bin/python -m agrl.train +experiment=switch_finetune reward.use_continuous_action=false \
    method.baseline=docs/results/baseline_2026-12-03/fixed_baseline.pt \
    ppo.minibatch_size=512 ppo.learning_rate=5e-4 ppo.total_frames=1310720 \
    seed=$seed threads=1 progress=false "$@" hydra.run.dir=$out/$name > /dev/null 2>&1 || echo "FAILED $name" >> $log
  echo "$(date -u +%H:%M:%S) done  $name: $(tail -n 1 $out/$name/train.log | cut -c1-160)" >> $log
}
for seed in 0 1 2; do
  train ft_s$seed $seed &
  train quiet_s$seed $seed ppo.minibatch_size=4096 ppo.learning_rate=1e-3 ppo.total_frames=1638400 &
  wait
done
.venv/bin/python -m agrl.export $out/ft_s0 $out/ft_s1 $out/ft_s2 $out/ft_soup.pt >> $log 2>&1
.venv/bin/python -m agrl.export $out/quiet_s0 $out/quiet_s1 $out/quiet_s2 $out/quiet_soup.pt >> $log 2>&1
evaluate() {  # name checkpoint seed
  .venv/bin/python -m agrl.evaluate checkpoint=$2 episodes=10000 seed=$3 trajectories=0 \
    hydra.run.dir=$out/eval_$1_$3 > /dev/null 2>&1 || echo "FAILED eval $1 $3" >> $log
  echo "$1 seed $3: $(python3 -c "import json,sys; d=json.load(open(sys.argv[1])); print({k: d[k] for k in ('success_rate', 'instructions_per_episode', 'outcomes') if k in d})" $out/eval_$1_$3/eval.json 2>&1)" >> $log
}
for name in ft_s0 ft_s1 ft_s2 quiet_s0 quiet_s1 quiet_s2 ft_soup quiet_soup; do
  checkpoint=$out/$name; [[ $name == *soup ]] && checkpoint=$out/$name.pt
  evaluate $name $checkpoint 777 &
  evaluate $name $checkpoint 4242 &
  wait
done
find $out -name checkpoints -type d -exec rm -r {} +; find $out -name episodes.csv -delete
find $out -mindepth 2 -name '*.pt' -delete
echo "$(date -u +%H:%M:%S) sitting done" >> $log
