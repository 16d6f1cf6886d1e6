#!/usr/bin/env bash
# Algorithm 1 (Z from scratch) with and without the KL limit of the previous sitting (ppo.target_kl=0.03) at uniform
# 100 m/s, from the two-stage shipped baseline; 3 seeds, the two interleaved per seed, one run at a time on the
# otherwise idle VM, 2 torch threads; the races' settings of moving.md (4-minute budget, 256 episodes every 15 s,
# stop at 99 %).
#   bash docs/results/runs/target_kl_algorithm1_2026-12-03/sitting.sh
#   python -m agrl.report runs docs/results/runs/target_kl_algorithm1_2026-12-03 --times 15 30 60 90
set -u
cd "$(git rev-parse --show-toplevel)"
out=docs/results/runs/target_kl_algorithm1_2026-12-03
log=$out/sitting.log
py=.venv/bin/python
stamp() { echo "## $(date -u +%FT%TZ) commit $(git rev-parse --short HEAD) load $(cut -d' ' -f1-3 /proc/loadavg): $*" >> "$log"; }
race() {  # race <name> <seed> <overrides...>
  local name=$1 seed=$2; shift 2
  stamp "$name seed $seed"
  $py -m agrl.train progress=false "seed=$seed" ppo.max_minutes=4 target_success=0.99 \
      eval.interval_seconds=15 "$@" "hydra.run.dir=$out/${name}_s$seed" >> "$log" 2>&1
}
for seed in 0 1 2; do
  race u100_reuse "$seed" task=uniform speed=100 method=reuse
  race u100_reuse_kl "$seed" task=uniform speed=100 method=reuse ppo.target_kl=0.03
done
find $out -name '*.pt' -delete; find $out -name checkpoints -type d -empty -delete; find $out -name episodes.csv -delete
stamp done
