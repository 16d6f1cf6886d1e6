#!/bin/bash
# The first iterations of pre-trained and reuse at 100 m/s, one run at a time, alternating (warm compile cache).
# Prints, per iteration: (iteration s, collection s, relabelling s).
cd "$(git rev-parse --show-toplevel)"
for rep in 1 2; do for m in pretrained reuse; do
  .venv/bin/python -m agrl.train progress=false task=uniform speed=100 method=$m seed=0 ppo.total_frames=98304 ppo.max_minutes=0 eval.interval=0 eval.episodes=100 hydra.run.dir=/tmp/first_${m}_$rep > /dev/null 2>&1
  .venv/bin/python -c "
from agrl.report import read_metrics
rows=read_metrics('/tmp/first_${m}_$rep')
print('$m $rep', [(round(r['time/iteration_seconds'],2), round(32768/r['time/collection_decisions_per_second'],2), round(r.get('time/reuse_seconds',0),2)) for r in rows])
"
done; done
