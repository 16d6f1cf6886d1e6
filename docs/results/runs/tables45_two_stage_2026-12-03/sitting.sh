#!/usr/bin/env bash
# Tables 4-5's seven other settings (uniform 10, 20, 50 m/s; curved radius 1000, 2000, 5000 m; the irregular
# destination) rerun with everything as a user gets it since 2026-12-03 (later morning): the two-stage shipped
# baseline (6.9 instructions per episode), today's default reward (position shaping + switch cost 0.1). Scratch,
# Algorithm 1 (Z from scratch), reuse + B (Z from B's weights) and pre-training, 3 seeds, methods interleaved per
# seed, one run at a time on the otherwise idle VM, 2 torch threads; the protocol of moving.md's 2026-12-02 sweep
# (4-minute budget, 256 episodes every 15 s of training, stop at 99 %, 1000 final episodes).
#   bash docs/results/runs/tables45_two_stage_2026-12-03/sitting.sh
#   python -m agrl.report moving docs/results/runs/tables45_two_stage_2026-12-03
#   python -m agrl.report runs docs/results/runs/tables45_two_stage_2026-12-03 --times 15 30 60 120
set -u
cd "$(git rev-parse --show-toplevel)"
out=docs/results/runs/tables45_two_stage_2026-12-03
log=$out/sitting.log
py=.venv/bin/python
stamp() { echo "## $(date -u +%FT%TZ) commit $(git rev-parse --short HEAD) load $(cut -d' ' -f1-3 /proc/loadavg): $*" >> "$log"; }
race() {  # race <name> <seed> <overrides...>
  local name=$1 seed=$2; shift 2
  stamp "$name seed $seed"
  $py -m agrl.train progress=false "seed=$seed" ppo.max_minutes=4 target_success=0.99 \
      eval.interval_seconds=15 "$@" "hydra.run.dir=$out/${name}_s$seed" >> "$log" 2>&1
}
for setting in "uniform speed=10" "uniform speed=20" "uniform speed=50" \
               "curved radius=1000" "curved radius=2000" "curved radius=5000" "irregular"; do
  set -- $setting
  short=$1${2:+_${2#*=}}
  task="task=$1 ${2:-}"
  for seed in 0 1 2; do
    race ${short}_scratch "$seed" $task method=scratch
    race ${short}_reuse "$seed" $task method=reuse
    race ${short}_reuseB "$seed" $task method=reuse method.start_from_baseline=true
    race ${short}_pretrained "$seed" $task method=pretrained
  done
done
find $out -name '*.pt' -delete; find $out -name checkpoints -type d -empty -delete; find $out -name episodes.csv -delete
stamp done
