#!/bin/bash
# Today's figures for docs/benchmarks.md ("Current figures"): `make bench`'s three commands, one at a time on the
# otherwise idle VM, torch's default threads (2), then `python -m agrl.train +experiment=fast` (seed 0) as the VM's
# speed calibration against the earlier sittings. JSON lines into this folder; the load before each command in sitting.log.
#   bash docs/results/runs/bench_2026-12-03/sitting.sh
cd "$(git rev-parse --show-toplevel)"
out=docs/results/runs/bench_2026-12-03
log=$out/sitting.log
echo "$(date -u +%FT%H:%M:%S) sitting starts at commit $(git rev-parse --short HEAD)" >> $log
timed() {  # name output command...
  local name=$1 output=$2; shift 2
  echo "$(date -u +%H:%M:%S) start $name load $(cut -d' ' -f1-3 /proc/loadavg)" >> $log
  local start=$(date +%s.%N)
  "$@" > "$output" 2> "$out/$name.stderr" || echo "FAILED $name" >> $log
  echo "$(date -u +%H:%M:%S) done  $name: $(python3 -c "print(round($(date +%s.%N) - $start, 1))") s" >> $log
}
if [ "$1" != threads ]; then
timed bench $out/bench.jsonl .venv/bin/python -m agrl.bench
timed bench_reuse $out/bench_reuse.jsonl .venv/bin/python -m agrl.bench_reuse
timed bench_peer $out/bench_peer.jsonl .venv/bin/python -m agrl.bench_peer --trainers agrl agrl-compiled stable-baselines3 floor
timed fast_s0 /dev/null .venv/bin/python -m agrl.train +experiment=fast seed=0 progress=false hydra.run.dir=$out/fast_s0
python3 -c "import json; d=json.load(open('$out/fast_s0/eval/eval.json')); print('fast_s0: training', d['training_wall_time_s'], 's,', d['iterations'], 'iterations,', d['success_rate'], 'success,', round(d['instructions_per_episode'], 2), 'instructions')" >> $log
rm -rf $out/fast_s0/checkpoints $out/fast_s0/eval/episodes.csv
fi
# Added after the first pass (15:48), `bash .../sitting.sh threads`: the calibration run on one torch thread against
# two, A B A B.
if [ "$1" = threads ]; then
  for round in 1 2; do
    for threads in 1 2; do
      name=fast_s0_threads${threads}_round$round
      timed $name /dev/null .venv/bin/python -m agrl.train +experiment=fast seed=0 threads=$threads progress=false hydra.run.dir=$out/$name
      python3 -c "import json; d=json.load(open('$out/$name/eval/eval.json')); print('$name: training', d['training_wall_time_s'], 's,', d['iterations'], 'iterations,', d['success_rate'], 'success')" >> $log
      rm -rf $out/$name/checkpoints $out/$name/eval/episodes.csv
    done
  done
fi
find $out -name '*.stderr' -empty -delete
echo "$(date -u +%H:%M:%S) sitting done" >> $log
