#!/bin/bash
# One command at a time on the otherwise idle VM, after the fused simulator's two compiler options and the
# relabelling's single passes (docs/benchmarks.md, 2026-12-02 evening). BASE is a checkout of the commit before
# them (eee4271), for the A/B rows; its own conf/ is used.
#   1. bench_reuse, base against new, alternating (uniform 50 and 100 m/s)
#   2. python -m agrl.bench (new)
#   3. the first iterations at 100 m/s (../first_iteration_2026-12-02/first.sh's runs)
#   4. make train's command twice (time to 99.5 %)
#   5. uniform 100 m/s: pre-trained, Algorithm 1 and reuse + B, 3 seeds, 4-minute budget (moving.md's protocol)
cd "$(git rev-parse --show-toplevel)"
out=docs/results/runs/fast_simulator_2026-12-02
BASE=${BASE:-/tmp/base}
log=$out/sitting.log
stamp() { echo "$(date -u +%H:%M:%S) load $(cut -d' ' -f1 /proc/loadavg) $*" >> $log; }
stamp "start commit $(git rev-parse --short HEAD) base $(git -C $BASE rev-parse --short HEAD)"
for speed in 50 100; do
  for round in 1 2; do
    for side in base new; do
      dir=$PWD; [ $side = base ] && dir=$BASE
      stamp "bench_reuse speed=$speed $side"
      (cd $dir && PYTHONPATH=$dir $OLDPWD/.venv/bin/python -m agrl.bench_reuse --candidates 16 --repeats 3 \
        task=uniform speed=$speed 2>&1 | tail -n 1) >> $out/bench_reuse.jsonl
    done
  done
done
stamp "bench"
.venv/bin/python -m agrl.bench > $out/bench.jsonl 2>&1
for rep in 1 2; do for m in pretrained reuse; do
  stamp "first iterations $m $rep"
  .venv/bin/python -m agrl.train progress=false task=uniform speed=100 method=$m seed=0 ppo.total_frames=98304 \
    ppo.max_minutes=0 eval.interval=0 eval.episodes=100 hydra.run.dir=$out/first_${m}_$rep > /dev/null 2>&1
done; done
for rep in 1 2; do
  stamp "make train $rep"
  .venv/bin/python -m agrl.train hydra.run.dir=$out/make_train_$rep > $out/make_train_$rep.log 2>&1
  tail -n 2 $out/make_train_$rep/train.log >> $log
done
for seed in 0 1 2; do
  for variant in pretrained reuse reuseB; do
    case $variant in
      pretrained) extra="method=pretrained" ;;
      reuse) extra="method=reuse" ;;
      reuseB) extra="method=reuse method.start_from_baseline=true" ;;
    esac
    name=race_${variant}_s$seed
    stamp "start $name"
    .venv/bin/python -m agrl.train progress=false task=uniform speed=100 seed=$seed ppo.max_minutes=4 \
      target_success=0.99 eval.interval_seconds=15 $extra hydra.run.dir=$out/$name > $out/$name.train.log 2>&1
    tail -n 1 $out/$name/train.log | cut -c 40-300 >> $log
  done
done
stamp done
