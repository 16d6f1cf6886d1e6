#!/usr/bin/env bash
# Iterations to a 99.5 % periodic evaluation (every 2 iterations) with the default curriculum step (0.1) and a
# larger one (0.3), seeds 0-2, run from the repository root two at a time on one thread each: a count of
# iterations, which the machine's load does not change (its wall times are not comparable).
set -u
out=docs/results/runs/curriculum_step_2026-12-02
py=.venv/bin/python
one() {  # one <name> <seed> <overrides...>
  local name=$1 seed=$2; shift 2
  OMP_NUM_THREADS=1 $py -m agrl.train threads=1 progress=false eval.interval=2 eval.trajectory_image=false \
      ppo.max_minutes=0 ppo.total_frames=3000000 "seed=$seed" "$@" "hydra.run.dir=$out/${name}_s$seed" \
      > "$out/${name}_s$seed.log" 2>&1
}
for seed in 0 1 2; do
  one step0.1 "$seed" &
  one step0.3 "$seed" curriculum.scale_step=0.3
  wait
done
