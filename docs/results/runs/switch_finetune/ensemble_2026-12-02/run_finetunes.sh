#!/bin/bash
# Since 2026-12-03 +experiment=switch_finetune is the two-stage recipe's stage 2; the overrides right after it give
# the experiment as this ran (both shaping terms, minibatch 512, 5e-4, 40 iterations, the 2026-12-01 baseline).
# Five stage-2 fine-tunes with the quieter update (the recipe of switch_cost.md, "Averaging the quieter fine-tunes"),
# two at a time on one torch thread each: their frame budgets, not wall time, bound them.
cd "$(git rev-parse --show-toplevel)"
export OMP_NUM_THREADS=1
out=docs/results/runs/switch_finetune/ensemble_2026-12-02
run() {
  echo "$(date -u +%H:%M:%S) start ft_s$1 load $(cut -d' ' -f1 /proc/loadavg)" >> $out/log.txt
  .venv/bin/python -m agrl.train +experiment=switch_finetune reward.use_continuous_action=true ppo.minibatch_size=512 ppo.learning_rate=5e-4 ppo.total_frames=1310720 method.baseline=docs/results/baseline_2026-12-01/fixed_baseline.pt progress=false threads=1 seed=$1 \
    ppo.minibatch_size=4096 ppo.learning_rate=1e-3 ppo.total_frames=1638400 \
    hydra.run.dir=$out/ft_s$1 > $out/ft_s$1.train.log 2>&1
  echo "$(date -u +%H:%M:%S) done ft_s$1" >> $out/log.txt
}
(run 0; run 2; run 4) &
(run 1; run 3) &
wait
