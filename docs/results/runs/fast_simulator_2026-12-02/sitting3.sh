#!/bin/bash
# After sitting2.sh, same conditions: the simulator and env rows of python -m agrl.bench (compiled), from the base
# checkout (BASE, commit eee4271) and from this one, alternating.
cd "$(git rev-parse --show-toplevel)"
out=docs/results/runs/fast_simulator_2026-12-02
BASE=${BASE:-/tmp/base}
log=$out/sitting3.log
stamp() { echo "$(date -u +%H:%M:%S) load $(cut -d' ' -f1 /proc/loadavg) $*" >> $log; }
stamp "start commit $(git rev-parse --short HEAD) base $(git -C $BASE rev-parse --short HEAD)"
for rep in 1 2; do
  for side in base new; do
    dir=$PWD; [ $side = base ] && dir=$BASE
    stamp "bench $side $rep"
    (cd $dir && PYTHONPATH=$dir $OLDPWD/.venv/bin/python -m agrl.bench --modes compiled --guide-formats checkpoint \
      2>&1 | grep decisions_per_second | sed "s/^{/{\"side\": \"$side\", /") >> $out/bench_ab.jsonl
  done
done
stamp done
