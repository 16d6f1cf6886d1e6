#!/usr/bin/env bash
# sitting.sh's seed 0 again for `fast` and `mb1024`, whose first runs compiled the loss with a cold inductor cache
# (first iteration 12 s and 9 s against 3-4 s); the three recipes again, one command at a time, then the same
# untimed evaluations. Output: sitting_warm.log, <variant>_s0_warm/.
set -u
cd "$(git rev-parse --show-toplevel)"
out=docs/results/runs/fast_update_2026-12-03
log=$out/sitting_warm.log
py=.venv/bin/python
stamp() { echo "## $(date -u +%FT%TZ) commit $(git rev-parse --short HEAD) load $(cut -d' ' -f1-3 /proc/loadavg): $*" >> "$log"; }
for variant in fast epochs3 mb1024; do
  case $variant in
    fast) overrides="" ;;
    epochs3) overrides="ppo.epochs=3" ;;
    mb1024) overrides="ppo.minibatch_size=1024" ;;
  esac
  stamp "train $variant seed 0 (warm cache)"
  $py -m agrl.train +experiment=fast $overrides progress=false seed=0 "hydra.run.dir=$out/${variant}_s0_warm" >> "$log" 2>&1
done
for run in $out/*_s0_warm; do
  for seed in 777 4242; do
    stamp "evaluate $run on seed $seed"
    $py -m agrl.evaluate "checkpoint=$run" episodes=10000 seed=$seed trajectories=0 \
        "output_dir=$run/eval_$seed" "hydra.run.dir=$run/eval_$seed" >> "$log" 2>&1
  done
done
find $out -name '*.pt' -delete; find $out -name checkpoints -type d -empty -delete; find $out -name episodes.csv -delete
stamp done
