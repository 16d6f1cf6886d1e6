#!/bin/bash
# Table 3 again with today's code, on the idle 2-core VM, ONE training at a time (nothing else running): the four
# paper variants and the switch cost (not in the paper) at k = 0.1 (the default) and 0.3, 3 seeds, methods
# interleaved per seed. Every run: defaults otherwise (the `make experiments-table3` settings: stop at the 99.5 %
# periodic evaluation or after 5 minutes of training). Then, untimed, each final agent on 10 000 episodes
# from seeds 777 and 4242 (never used in training or in any stop).
#   bash docs/results/runs/table3_2026-12-03/sitting.sh
#   python -m agrl.report table3 docs/results/runs/table3_2026-12-03 --independent eval_777 eval_4242
cd "$(git rev-parse --show-toplevel)"
out=docs/results/runs/table3_2026-12-03
log=$out/sitting.log
echo "$(date -u +%FT%H:%M:%S) sitting starts at commit $(git rev-parse --short HEAD)" >> $log
for seed in 0 1 2; do
  for variant in none continuous position both switch0.1 switch0.3; do
    case $variant in
      switch0.1) overrides="reward=switch reward.switch_cost=0.1" ;;
      switch0.3) overrides="reward=switch reward.switch_cost=0.3" ;;
      *) overrides="reward=$variant" ;;
    esac
    run=$out/${variant}_s$seed
    echo "$(date -u +%H:%M:%S) start $run load $(cut -d' ' -f1-3 /proc/loadavg)" >> $log
    .venv/bin/python -m agrl.train $overrides seed=$seed ppo.max_minutes=5 progress=false \
      hydra.run.dir=$run > /dev/null 2>&1 || echo "FAILED $run" >> $log
    echo "$(date -u +%H:%M:%S) done  $run: $(tail -n 1 $run/train.log | cut -c1-160)" >> $log
  done
done
echo "$(date -u +%H:%M:%S) training done; independent evaluations (untimed)" >> $log
for run in $out/*_s[0-9]; do
  for ev in 777 4242; do
    .venv/bin/python -m agrl.evaluate checkpoint=$run episodes=10000 seed=$ev trajectories=0 \
      hydra.run.dir=$run/eval_$ev > /dev/null 2>&1 || echo "FAILED eval $run $ev" >> $log
  done
done
find $out -name '*.pt' -delete; find $out -name checkpoints -type d -empty -delete; find $out -name episodes.csv -delete
echo "$(date -u +%H:%M:%S) sitting done" >> $log
