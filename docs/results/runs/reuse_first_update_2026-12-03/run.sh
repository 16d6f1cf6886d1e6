#!/usr/bin/env bash
# The first update of reuse + B against pre-training's, from the same first batch, per setting (diagnose.py);
# untimed, one torch thread. Output: first_update.jsonl, one line per setting, seed and method.
#   bash docs/results/runs/reuse_first_update_2026-12-03/run.sh
set -eu
cd "$(git rev-parse --show-toplevel)"
out=docs/results/runs/reuse_first_update_2026-12-03
: > $out/first_update.jsonl
for setting in "task=uniform speed=10" "task=uniform speed=50" "task=uniform speed=100" "task=curved radius=500" \
               "task=curved radius=1000"; do
  for seed in 0 1 2; do
    .venv/bin/python $out/diagnose.py $setting seed=$seed 2>/dev/null | grep '^{' >> $out/first_update.jsonl
  done
done
