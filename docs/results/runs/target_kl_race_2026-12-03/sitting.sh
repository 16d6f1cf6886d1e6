#!/usr/bin/env bash
# Reuse + B with its first updates held to a KL limit (ppo.target_kl=0.03: stop an update's minibatches once a
# minibatch's approximate KL exceeds 0.045; moving.md, "Why reuse + B's first update moves the policy so far"),
# against pre-training with the same setting (whose updates stay below it), at uniform 100 m/s and curved radius
# 500 m; 3 seeds, methods interleaved per seed, one run at a time on the otherwise idle VM, 2 torch threads; the
# races' settings of moving.md (4-minute budget, 256 episodes every 15 s, stop at 99 %).
#   bash docs/results/runs/target_kl_race_2026-12-03/sitting.sh
#   python -m agrl.report runs docs/results/runs/target_kl_race_2026-12-03 --times 15 30 60 90
set -u
cd "$(git rev-parse --show-toplevel)"
out=docs/results/runs/target_kl_race_2026-12-03
log=$out/sitting.log
py=.venv/bin/python
stamp() { echo "## $(date -u +%FT%TZ) commit $(git rev-parse --short HEAD) load $(cut -d' ' -f1-3 /proc/loadavg): $*" >> "$log"; }
race() {  # race <name> <seed> <overrides...>
  local name=$1 seed=$2; shift 2
  stamp "$name seed $seed"
  $py -m agrl.train progress=false "seed=$seed" ppo.max_minutes=4 target_success=0.99 ppo.target_kl=0.03 \
      eval.interval_seconds=15 "$@" "hydra.run.dir=$out/${name}_s$seed" >> "$log" 2>&1
}
for setting in u100 r500; do
  case $setting in
    u100) task="task=uniform speed=100" ;;
    r500) task="task=curved radius=500" ;;
  esac
  for seed in 0 1 2; do
    race ${setting}_pretrained "$seed" $task method=pretrained
    race ${setting}_reuseB "$seed" $task method=reuse method.start_from_baseline=true
  done
done
find $out -name '*.pt' -delete; find $out -name checkpoints -type d -empty -delete; find $out -name episodes.csv -delete
stamp done
