"""The tables of docs/results/moving.md, "The paper's observation", from the runs' TensorBoard logs and eval.json.

python docs/results/runs/paper_observation_2026-12-02/summarise.py docs/results/runs/paper_observation_2026-12-02

(Now the same as `python -m agrl.report runs <folder> --times 60 120 180 240 300`, which this calls.)
"""

import sys

from agrl.report import main

if __name__ == "__main__":
    sys.exit(main(["runs", sys.argv[1], "--times", "60", "120", "180", "240", "300"]))
