#!/usr/bin/env bash
# Does a wider network (2 x 256) carry the two-stage recipe past 99.8 % at <= 7 instructions? Per seed: stage 1 =
# the defaults (switch cost 0.1) at 2 x 256; stage 2 = the quieter fine-tune at 0.3 (minibatch 4096, learning rate
# 1e-3, 50 iterations) from it; then 10 000 episodes from seeds 777 and 4242. One torch thread per command; the
# iteration counts, not the wall times, are the measure. Usage: run.sh <seed>
# Since 2026-12-03 reward=switch has no continuous-action term and +experiment=switch_finetune is another recipe;
# reward.use_continuous_action=true and the overrides right after the experiment give both as this ran.
set -eu
seed=$1
out=docs/results/runs/switch_finetune/wide256_2026-12-03
py=.venv/bin/python
wide=("agent.actor_hidden=[256,256]" "agent.critic_hidden=[256,256]")
export OMP_NUM_THREADS=1
$py -m agrl.train reward.use_continuous_action=true threads=1 progress=false seed=$seed ppo.max_minutes=0 ppo.total_frames=4000000 "${wide[@]}" \
    "hydra.run.dir=$out/stage1_s$seed" > "$out/stage1_s$seed.log" 2>&1
$py -m agrl.train +experiment=switch_finetune reward.use_continuous_action=true ppo.minibatch_size=512 ppo.learning_rate=5e-4 ppo.total_frames=1310720 threads=1 progress=false seed=$seed "${wide[@]}" \
    "method.baseline=$out/stage1_s$seed" ppo.minibatch_size=4096 ppo.learning_rate=1e-3 ppo.total_frames=1638400 \
    "hydra.run.dir=$out/ft_s$seed" > "$out/ft_s$seed.log" 2>&1
for eval_seed in 777 4242; do
  $py -m agrl.evaluate "checkpoint=$out/ft_s$seed" episodes=10000 seed=$eval_seed trajectories=0 \
      "output_dir=$out/ft_s$seed/eval_$eval_seed" "hydra.run.dir=$out/ft_s$seed/eval_$eval_seed" > /dev/null 2>&1
done
