#!/bin/bash
# Since 2026-12-03 +experiment=switch_finetune is the two-stage recipe's stage 2; the overrides right after it give
# the experiment as this ran (both shaping terms, minibatch 512, 5e-4, 40 iterations, the 2026-12-01 baseline).
# Weight average of three stage-2 fine-tunes with the quieter update (minibatch 4096, learning rate 1e-3,
# 50 iterations: switch_cost.md, "Quieter fine-tunes"), then 10 000-episode evaluations on seeds 777 and 4242.
cd "$(git rev-parse --show-toplevel)"
export OMP_NUM_THREADS=1  # one core for this sitting; the other runs the reuse ablations
out=docs/results/runs/switch_finetune/soup_mb4096_2026-12-02
for seed in 0 1 2; do
  echo "$(date -u +%H:%M:%S) start ft_s$seed load $(cut -d' ' -f1 /proc/loadavg)" >> $out/log.txt
  .venv/bin/python -m agrl.train +experiment=switch_finetune reward.use_continuous_action=true ppo.minibatch_size=512 ppo.learning_rate=5e-4 ppo.total_frames=1310720 method.baseline=docs/results/baseline_2026-12-01/fixed_baseline.pt progress=false threads=1 seed=$seed \
    ppo.minibatch_size=4096 ppo.learning_rate=1e-3 ppo.total_frames=1638400 \
    hydra.run.dir=$out/ft_s$seed > $out/ft_s$seed.train.log 2>&1
done
.venv/bin/python -m agrl.export $out/ft_s0 $out/ft_s1 $out/ft_s2 $out/soup.pt >> $out/log.txt 2>&1
for ev in 777 4242; do
  for name in soup ft_s0 ft_s1 ft_s2; do
    ck=$out/$name; [ $name = soup ] && ck=$out/soup.pt
    .venv/bin/python -m agrl.evaluate checkpoint=$ck episodes=10000 seed=$ev trajectories=0 \
      hydra.run.dir=$out/eval_${name}_$ev > $out/eval_${name}_$ev.log 2>&1
    echo "$name seed $ev: $(tail -n 1 $out/eval_${name}_$ev.log | cut -c1-400)" >> $out/log.txt
  done
done
echo "$(date -u +%H:%M:%S) done" >> $out/log.txt
