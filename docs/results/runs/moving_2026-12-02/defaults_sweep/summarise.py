"""The table of docs/results/moving.md, "Uniform 50 m/s with today's defaults", from the runs' TensorBoard logs and eval.json.

python docs/results/runs/moving_2026-12-02/defaults_sweep/summarise.py docs/results/runs/moving_2026-12-02/defaults_sweep
"""

import json
import statistics
import sys
from pathlib import Path

from agrl.report import read_metrics

TIMES = (60, 120, 180, 240)  # s of training: evaluation success at the last evaluation before each


def summary(run: Path) -> dict:
    rows = read_metrics(run)
    evaluations = [(row["time/wall_time"], row["eval/success_rate"]) for row in rows
                   if "eval/success_rate" in row and "time/wall_time" in row]
    iterations = [row for row in rows if "time/iteration_seconds" in row]
    reached = next((time for time, success in evaluations if success >= 0.95), None)
    at = [max((success for time, success in evaluations if time <= limit), default=None) for limit in TIMES]
    final = json.loads((run / "eval" / "eval.json").read_text())
    later = [row["time/iteration_seconds"] for row in iterations[1:]]
    relabel = [row.get("time/reuse_seconds", 0.0) for row in iterations[1:]]
    return {
        "run": run.name, "to_95": reached, "at": at, "final": final["success_rate"],
        "instructions": final["instructions_per_episode"], "iterations": len(iterations),
        "median_iteration": statistics.median(later) if later else None,
        "median_relabel": statistics.median(relabel) if relabel else None,
        "first_iteration": iterations[0]["time/iteration_seconds"] if iterations else None,
        "first_relabel": iterations[0].get("time/reuse_seconds") if iterations else None,
        "start": evaluations[0][1] if evaluations else None,
    }


def cell(value, fmt="{:.1f}"):
    return "-" if value is None else fmt.format(value)


if __name__ == "__main__":
    root = Path(sys.argv[1])
    print("| run | evaluation before training | best evaluation by 60 / 120 / 180 / 240 s | s to 95 % "
          "| final success (1000) | instructions | iterations | median s / iteration (relabelling) "
          "| first iteration s (relabelling) |")
    print("|---|---:|---|---:|---:|---:|---:|---:|---:|")
    for run in sorted(path for path in root.iterdir() if (path / "eval" / "eval.json").is_file()):
        s = summary(run)
        at = " / ".join(cell(value * 100 if value is not None else None, "{:.0f}") for value in s["at"])
        print(f"| {s['run']} | {cell(s['start'] * 100, '{:.1f} %')} | {at} % | {cell(s['to_95'], '{:.0f}')} "
              f"| {s['final'] * 100:.1f} % | {s['instructions']:.1f} | {s['iterations']} "
              f"| {cell(s['median_iteration'], '{:.2f}')} ({cell(s['median_relabel'], '{:.2f}')}) "
              f"| {cell(s['first_iteration'])} ({cell(s['first_relabel'])}) |")
