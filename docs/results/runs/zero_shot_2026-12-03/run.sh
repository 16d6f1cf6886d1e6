#!/bin/bash
# Zero-shot: each shipped baseline of the last days flies every moving-destination setting of Tables 4-5 before any
# training (what pre-training and reuse + B start from), 1000 episodes from seed 777 per setting, no trajectories.
# Untimed (two evaluations at a time). Output: one eval.json per (baseline, setting) and summary.md.
#   bash docs/results/runs/zero_shot_2026-12-03/run.sh
cd "$(git rev-parse --show-toplevel)"
out=docs/results/runs/zero_shot_2026-12-03
declare -A baselines=(
  [two_stage]=agrl/baselines/fixed_baseline.pt
  [stage1_2026-12-03]=docs/results/baseline_2026-12-03/fixed_baseline.pt
  [2026-12-01]=docs/results/baseline_2026-12-01/fixed_baseline.pt
)
settings=("task=fixed" "task=uniform speed=10" "task=uniform speed=20" "task=uniform speed=50" "task=uniform speed=100"
          "task=curved radius=500" "task=curved radius=1000" "task=curved radius=2000" "task=curved radius=5000"
          "task=irregular")
for name in two_stage stage1_2026-12-03 2026-12-01; do
  for setting in "${settings[@]}"; do
    tag=$(echo "$setting" | sed 's/task=//; s/ speed=/_/; s/ radius=/_/')
    .venv/bin/python -m agrl.evaluate checkpoint=${baselines[$name]} $setting episodes=1000 seed=777 trajectories=0 \
      hydra.run.dir=$out/$name/$tag > /dev/null 2>&1 &
    while [ "$(jobs -r | wc -l)" -ge 2 ]; do sleep 1; done
  done
done
wait
find $out -name episodes.csv -delete
.venv/bin/python - "$out" <<'PY' > $out/summary.md
import json, sys
from pathlib import Path
out = Path(sys.argv[1])
names = ["two_stage", "stage1_2026-12-03", "2026-12-01"]
tags = sorted({p.parent.name for p in out.glob("*/*/eval.json")},
              key=lambda tag: (["fixed", "uniform", "curved", "irregular"].index(tag.split("_")[0]),
                               float(tag.split("_")[1]) if "_" in tag else 0))
print("| setting | " + " | ".join(f"{name}: success, instructions" for name in names) + " |")
print("|---|" + "---|" * len(names))
for tag in tags:
    cells = []
    for name in names:
        record = json.loads((out / name / tag / "eval.json").read_text())
        cells.append(f"{100 * record['success_rate']:.1f} %, {record['instructions_per_episode']:.1f}")
    print(f"| {tag} | " + " | ".join(cells) + " |")
PY
cat $out/summary.md
