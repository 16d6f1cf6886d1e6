#!/bin/bash
# More seeds (3-5) of sitting.sh's comparison: the switch cost at k = 0.1 with both shaping terms (`make train`'s
# default reward) and with the position term alone, interleaved per seed, one training at a time on the otherwise
# idle VM, 2 torch threads; then, untimed, 10 000 episodes from seeds 777 and 4242.
#   bash docs/results/runs/position_switch_2026-12-03/sitting2.sh
cd "$(git rev-parse --show-toplevel)"
out=docs/results/runs/position_switch_2026-12-03
log=$out/sitting2.log
echo "$(date -u +%FT%H:%M:%S) sitting starts at commit $(git rev-parse --short HEAD)" >> $log
for seed in 3 4 5; do
  for variant in both position; do
    case $variant in
      both) overrides="reward=switch"; run=$out/both_k0.1_s$seed ;;
      position) overrides="reward=switch reward.use_continuous_action=false"; run=$out/k0.1_s$seed ;;
    esac
    echo "$(date -u +%H:%M:%S) start $run load $(cut -d' ' -f1-3 /proc/loadavg)" >> $log
    .venv/bin/python -m agrl.train $overrides seed=$seed ppo.max_minutes=5 progress=false \
      hydra.run.dir=$run > /dev/null 2>&1 || echo "FAILED $run" >> $log
    echo "$(date -u +%H:%M:%S) done  $run: $(tail -n 1 $run/train.log | cut -c1-160)" >> $log
  done
done
for run in $out/*_s[3-5]; do
  for ev in 777 4242; do
    .venv/bin/python -m agrl.evaluate checkpoint=$run episodes=10000 seed=$ev trajectories=0 \
      hydra.run.dir=$run/eval_$ev > /dev/null 2>&1 || echo "FAILED eval $run $ev" >> $log
  done
done
find $out -name '*.pt' -delete; find $out -name checkpoints -type d -empty -delete; find $out -name episodes.csv -delete
echo "$(date -u +%H:%M:%S) sitting done" >> $log
