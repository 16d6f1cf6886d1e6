#!/usr/bin/env bash
# A cheaper update for `+experiment=fast`? Three epochs instead of four, or minibatches of 1024 instead of 512 (half
# the optimiser steps), against the recipe as it is, seeds 0-2, recipes interleaved per seed, one command at a time
# on the otherwise idle VM; then each agent on 10 000 episodes from seeds 777 and 4242 (untimed).
#   bash docs/results/runs/fast_update_2026-12-03/sitting.sh
#   python -m agrl.report runs docs/results/runs/fast_update_2026-12-03 --times 20 25 30
set -u
cd "$(git rev-parse --show-toplevel)"
out=docs/results/runs/fast_update_2026-12-03
log=$out/sitting.log
py=.venv/bin/python
stamp() { echo "## $(date -u +%FT%TZ) commit $(git rev-parse --short HEAD) load $(cut -d' ' -f1-3 /proc/loadavg): $*" >> "$log"; }
for seed in 0 1 2; do
  for variant in fast epochs3 mb1024; do
    case $variant in
      fast) overrides="" ;;
      epochs3) overrides="ppo.epochs=3" ;;
      mb1024) overrides="ppo.minibatch_size=1024" ;;
    esac
    stamp "train $variant seed $seed"
    $py -m agrl.train +experiment=fast $overrides progress=false seed=$seed "hydra.run.dir=$out/${variant}_s$seed" >> "$log" 2>&1
  done
done
for run in $out/*_s[0-9]; do
  for seed in 777 4242; do
    stamp "evaluate $run on seed $seed"
    $py -m agrl.evaluate "checkpoint=$run" episodes=10000 seed=$seed trajectories=0 \
        "output_dir=$run/eval_$seed" "hydra.run.dir=$run/eval_$seed" >> "$log" 2>&1
  done
done
find $out -name '*.pt' -delete; find $out -name checkpoints -type d -empty -delete; find $out -name episodes.csv -delete
stamp done
