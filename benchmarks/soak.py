"""A long training run watched from outside: memory, decisions/s and the losses' finiteness over time.

    python -m benchmarks.soak --minutes 60 --out soak.jsonl            # a policy-reuse run at 100 m/s
    python -m benchmarks.soak --minutes 5 -- task=curved radius=500    # other overrides after --

Runs ``python -m agrl.train`` with the given overrides (default: ``task=uniform speed=100 method=reuse``, no
early stop) and samples the resident memory of the training process and its children every ``--every`` seconds.
At the end it reads the run's TensorBoard scalars and prints one JSON line per sample and a summary line:
resident memory at the start and end of the run (medians of its first and last tenths, after the first
iteration), decisions per second likewise, and whether every logged loss was finite. A memory leak shows as a
rising resident set; a slowdown (the relabelling's carried episodes piling up, say) as falling decisions per second.
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

DEFAULT_OVERRIDES = ("task=uniform", "speed=100", "method=reuse", "target_success=0", "progress=false")


def resident_bytes(pid: int) -> int:
    """Resident memory of ``pid`` and every process below it (the collector's workers, compile workers)."""
    total, pending = 0, [pid]
    while pending:
        current = pending.pop()
        try:
            status = Path(f"/proc/{current}/status").read_text()
            total += next(int(line.split()[1]) * 1024 for line in status.splitlines() if line.startswith("VmRSS:"))
            for task in Path(f"/proc/{current}/task").iterdir():
                pending += [int(child) for child in (task / "children").read_text().split()]
        except (OSError, StopIteration):
            continue
    return total


def window_median(rows: list[dict], key: str, first: bool) -> float:
    values = [row[key] for row in rows if row.get(key) is not None]
    tenth = max(1, len(values) // 10)
    return statistics.median(values[:tenth] if first else values[-tenth:])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.soak", description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=60.0, help="training time (ppo.max_minutes)")
    parser.add_argument("--every", type=float, default=10.0, help="seconds between memory samples")
    parser.add_argument("--out", type=Path, help="also write the JSON lines here")
    parser.add_argument("--run-dir", type=Path, help="the run directory (default: a temporary folder)")
    parser.add_argument("overrides", nargs="*", help="Hydra overrides for python -m agrl.train (after --)")
    args = parser.parse_args(argv)
    if args.minutes <= 0 or args.every <= 0:
        parser.error(f"--minutes {args.minutes:g} --every {args.every:g}: both must be > 0")

    run_dir = args.run_dir or Path(tempfile.mkdtemp(prefix="agrl_soak_")) / "run"
    overrides = [*DEFAULT_OVERRIDES, *args.overrides, f"ppo.max_minutes={args.minutes}", "ppo.total_frames=10000000000",
                 f"hydra.run.dir={run_dir}"]
    command = [sys.executable, "-m", "agrl.train", *overrides]
    start = time.monotonic()
    process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    samples = []
    while process.poll() is None:
        samples.append({"kind": "memory", "seconds": round(time.monotonic() - start, 1),
                        "resident_mib": round(resident_bytes(process.pid) / 2**20, 1)})
        time.sleep(args.every)
    stderr = process.stderr.read()
    if process.returncode != 0:
        print(f"soak: python -m agrl.train exited {process.returncode}: {stderr.strip().splitlines()[-1:]}",
              file=sys.stderr)
        return 1

    from agrl.report import read_metrics

    metrics = read_metrics(run_dir)
    iterations = [row for row in metrics if "time/decisions_per_second" in row]
    losses = [value for row in metrics for key, value in row.items() if key.startswith("loss/")]
    first_iteration_at = min((row["wall_time"] for row in iterations), default=0.0)
    training = [sample for sample in samples if sample["seconds"] > first_iteration_at + 30]
    summary = {
        "kind": "summary", "command": " ".join(["python -m agrl.train", *overrides]),
        "wall_seconds": round(time.monotonic() - start, 1), "iterations": len(iterations),
        "resident_mib_start": window_median(training, "resident_mib", first=True),
        "resident_mib_end": window_median(training, "resident_mib", first=False),
        "resident_mib_max": max(sample["resident_mib"] for sample in training),
        "decisions_per_second_start": round(window_median(iterations, "time/decisions_per_second", True)),
        "decisions_per_second_end": round(window_median(iterations, "time/decisions_per_second", False)),
        "losses_logged": len(losses), "losses_finite": all(math.isfinite(value) for value in losses),
        "final_eval_success": json.loads((run_dir / "eval" / "eval.json").read_text())["success_rate"],
    }
    summary["resident_change"] = round(summary["resident_mib_end"] / summary["resident_mib_start"] - 1, 3)
    rows = [*samples, *({"kind": "iteration", "seconds": round(row["wall_time"], 1),
                         "decisions_per_second": round(row["time/decisions_per_second"])} for row in iterations),
            summary]
    text = "\n".join(json.dumps(row) for row in rows)
    if args.out:
        args.out.write_text(text + "\n")
    print(json.dumps(summary))
    return 0


if __name__ == "__main__":
    sys.exit(main())
