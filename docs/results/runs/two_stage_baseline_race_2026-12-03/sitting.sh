#!/usr/bin/env bash
# The high-speed claim's two settings rerun from the two-stage baseline shipped since 2026-12-03 (later morning:
# make train's stage 1 fine-tuned at a switch cost of 0.3, 6.9 instructions per episode): uniform 100 m/s and curved
# radius 500 m; pre-training, reuse + B (Z from B's weights) and Algorithm 1 (Z from scratch), 3 seeds, methods
# interleaved per seed, one run at a time on the otherwise idle VM, 2 torch threads; the races' settings of moving.md
# (4-minute budget, 256 episodes every 15 s, stop at 99 %). Z trains with today's default reward (switch cost 0.1,
# B's stage 1's; its stage 2 paid 0.3). Output: sitting.log and one folder per run.
#   bash docs/results/runs/two_stage_baseline_race_2026-12-03/sitting.sh
#   python -m agrl.report runs docs/results/runs/two_stage_baseline_race_2026-12-03 --times 15 30 60 90
set -u
cd "$(git rev-parse --show-toplevel)"
out=docs/results/runs/two_stage_baseline_race_2026-12-03
log=$out/sitting.log
py=.venv/bin/python
stamp() { echo "## $(date -u +%FT%TZ) commit $(git rev-parse --short HEAD) load $(cut -d' ' -f1-3 /proc/loadavg): $*" >> "$log"; }
race() {  # race <name> <seed> <overrides...>
  local name=$1 seed=$2; shift 2
  stamp "$name seed $seed"
  $py -m agrl.train progress=false "seed=$seed" ppo.max_minutes=4 target_success=0.99 \
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
    race ${setting}_reuse "$seed" $task method=reuse
  done
done
find $out -name '*.pt' -delete; find $out -name checkpoints -type d -empty -delete; find $out -name episodes.csv -delete
stamp done
