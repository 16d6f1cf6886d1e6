#!/bin/bash
# After sitting.sh, same conditions: make train's command from the base checkout (BASE, commit eee4271) and from
# this one, alternating; then the PPO iteration against stable-baselines3 (python -m agrl.bench_peer, make bench's row).
cd "$(git rev-parse --show-toplevel)"
out=docs/results/runs/fast_simulator_2026-12-02
BASE=${BASE:-/tmp/base}
log=$out/sitting2.log
stamp() { echo "$(date -u +%H:%M:%S) load $(cut -d' ' -f1 /proc/loadavg) $*" >> $log; }
stamp "start commit $(git rev-parse --short HEAD) base $(git -C $BASE rev-parse --short HEAD)"
for rep in 1 2; do
  for side in base new; do
    dir=$PWD; [ $side = base ] && dir=$BASE
    stamp "make train $side $rep"
    (cd $dir && PYTHONPATH=$dir $OLDPWD/.venv/bin/python -m agrl.train hydra.run.dir=$OLDPWD/$out/ab_train_${side}_$rep \
      > $OLDPWD/$out/ab_train_${side}_$rep.log 2>&1)
    tail -n 2 $out/ab_train_${side}_$rep/train.log >> $log
  done
done
stamp "bench_peer"
.venv/bin/python -m agrl.bench_peer --trainers agrl stable-baselines3 floor > $out/bench_peer.jsonl 2>&1
stamp done
