#!/bin/bash
# After sitting.sh, whose seed-0 runs compiled with a cold inductor cache (first iterations of 11-27 s against 4 s):
# fast64 and fast128 seed 0 again with a warm cache, and +experiment=fast as it stands (both shaping terms, 2 x 64),
# seed 0, whose morning sitting took 24.7 s (results/ppo_geometry.md), to calibrate this VM's speed now.
# One run at a time on the idle VM, 2 threads.
#   bash docs/results/runs/fast_two_stage_2026-12-03/sitting_warm.sh
cd "$(git rev-parse --show-toplevel)"
out=docs/results/runs/fast_two_stage_2026-12-03/sitting
log=$out/sitting_warm.log
echo "$(date -u +%FT%H:%M:%S) sitting starts at commit $(git rev-parse --short HEAD)" >> $log
run() {  # name overrides...
  local name=$1; shift
  echo "$(date -u +%H:%M:%S) start $name load $(cut -d' ' -f1-3 /proc/loadavg)" >> $log
  .venv/bin/python -m agrl.train "$@" progress=false hydra.run.dir=$out/$name > /dev/null 2>&1 || echo "FAILED $name" >> $log
  echo "$(date -u +%H:%M:%S) done  $name: $(python3 -c "import json,sys; d=json.load(open(sys.argv[1])); print('training', d['training_wall_time_s'], 's,', d['iterations'], 'iterations,', d['success_rate'], 'success,', round(d['instructions_per_episode'], 2), 'instructions')" $out/$name/eval/eval.json 2>&1)" >> $log
}
run fast_reference_s0 +experiment=fast seed=0 threads=2
for width in 64 128; do
  nets="agent.actor_hidden=[$width,$width] agent.critic_hidden=[$width,$width]"
  run warm_fast${width}_s0_stage1 +experiment=fast reward.use_continuous_action=false $nets seed=0 threads=2
  run warm_fast${width}_s0_stage2 +experiment=switch_finetune method.baseline=$out/warm_fast${width}_s0_stage1 \
    $nets ppo.compile_loss=true seed=0 threads=2
done
find $out -name checkpoints -type d -exec rm -r {} +; find $out -name episodes.csv -delete
echo "$(date -u +%H:%M:%S) sitting done" >> $log
