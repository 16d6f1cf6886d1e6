#!/usr/bin/env bash
# The sitting of 2026-12-02 (night) for ppo.compile_loss, run from the repository root, one command at a time on
# the otherwise idle VM: the peer benchmark (agrl eager and compiled, SB3, the plain-PyTorch floor), then
# `make train`'s command A B A B, eager loss against compiled loss. Output: sitting.log, bench_peer.jsonl, train_*/.
set -u
out=docs/results/runs/compile_loss_2026-12-02
log=$out/sitting.log
py=.venv/bin/python
stamp() { echo "## $(date -u +%FT%TZ) commit $(git rev-parse --short HEAD) load $(cut -d' ' -f1-3 /proc/loadavg): $*" >> "$log"; }
for round in 1 2; do
  stamp "bench_peer round $round"
  $py -m agrl.bench_peer --iterations 6 --trainers agrl agrl-compiled stable-baselines3 floor >> "$out/bench_peer.jsonl" 2>> "$log"
done
for round in 1 2; do
  stamp "train eager round $round"
  $py -m agrl.train progress=false "hydra.run.dir=$out/train_eager_$round" >> "$log" 2>&1
  stamp "train compiled round $round"
  $py -m agrl.train progress=false ppo.compile_loss=true "hydra.run.dir=$out/train_compiled_$round" >> "$log" 2>&1
done
stamp done
