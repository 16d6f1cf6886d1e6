#!/usr/bin/env bash
# The sitting of 2026-12-03 for `+experiment=fast`, run from the repository root, one command at a time on the
# otherwise idle VM: `make train`'s command (the defaults) and the fast recipe, A B per seed, seeds 0-2; then every
# agent on 10 000 episodes from seeds 777 and 4242 (untimed). Output: sitting.log, <recipe>_s<seed>/ with eval_<seed>/.
set -u
out=docs/results/runs/fast_recipe_2026-12-03
log=$out/sitting.log
py=.venv/bin/python
stamp() { echo "## $(date -u +%FT%TZ) commit $(git rev-parse --short HEAD) load $(cut -d' ' -f1-3 /proc/loadavg): $*" >> "$log"; }
for seed in 0 1 2; do
  stamp "train default seed $seed"
  $py -m agrl.train progress=false seed=$seed "hydra.run.dir=$out/default_s$seed" >> "$log" 2>&1
  stamp "train fast seed $seed"
  $py -m agrl.train +experiment=fast progress=false seed=$seed "hydra.run.dir=$out/fast_s$seed" >> "$log" 2>&1
done
for run in default_s0 fast_s0 default_s1 fast_s1 default_s2 fast_s2; do
  for seed in 777 4242; do
    stamp "evaluate $run on seed $seed"
    $py -m agrl.evaluate "checkpoint=$out/$run" episodes=10000 seed=$seed trajectories=0 \
        "output_dir=$out/$run/eval_$seed" "hydra.run.dir=$out/$run/eval_$seed" >> "$log" 2>&1
  done
done
stamp done
