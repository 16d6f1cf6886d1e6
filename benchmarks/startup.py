"""How long a user waits: ``python -m benchmarks.startup`` prints JSON lines (as ``benchmarks.bench``).

- ``train_first_iteration_seconds``: seconds from starting ``python -m agrl.train`` on its defaults (a budget of one
  iteration, a 32-episode final evaluation) to its log line of iteration 1, the initial periodic evaluation
  included. Run once with an empty compile cache (``compile_cache=empty``: the simulator is compiled; torch's own
  kernel cache is whatever the machine has) and ``--repeats`` times after it (``compile_cache=warm``: loaded; the
  median is reported).
- ``gym_vector_env_start_seconds``: seconds from starting a Python process to the first step of
  ``gymnasium.make_vec("agrl/Guidance-v0", num_envs=4096, vectorization_mode="vector_entry_point")`` on its
  defaults, with the cache warm; ``gym_vector_env_decisions_per_second`` is the same env's speed after it.

Each measurement is a fresh process, run one at a time: on a machine doing other work the figures are not a
speed claim.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

from benchmarks.bench import emit, machine_record

#: The gymnasium vector env's probe: start-up to the first step, then decisions/s over 2 s of steps.
VECTOR_ENV_PROBE = """
import time
start = time.perf_counter()
import gymnasium, numpy as np, agrl
envs = gymnasium.make_vec(agrl.GYM_ENV_ID, num_envs={rows}, vectorization_mode="vector_entry_point")
envs.reset(seed=0)
actions = np.random.default_rng(0).integers(0, 7, size=(16, {rows}))
envs.step(actions[0])
first = time.perf_counter() - start
steps, begin = 0, time.perf_counter()
while time.perf_counter() - begin < 2.0:
    steps += 1
    envs.step(actions[steps % 16])
print(first, {rows} * steps / (time.perf_counter() - begin), envs.env.simulator.compiled)
"""


def first_iteration_seconds(run_dir: Path, environment: dict[str, str]) -> float:
    """Seconds from starting ``python -m agrl.train`` to its ``iter 1`` line."""
    command = [sys.executable, "-u", "-m", "agrl.train", f"hydra.run.dir={run_dir}", "progress=false",
               "ppo.total_frames=1", "eval.episodes=32"]
    start = time.perf_counter()
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                               env=environment)
    seconds = None
    for line in process.stdout:
        if seconds is None and "iter 1 |" in line:
            seconds = time.perf_counter() - start
    if process.wait() != 0 or seconds is None:
        raise RuntimeError(f"{' '.join(command)} failed (exit {process.returncode})")
    return seconds


def parse_args(argv: Sequence[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.startup", description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=3, help="warm runs of the training command (default 3)")
    parser.add_argument("--rows", type=int, default=4096, help="the vector env's rows (default 4096)")
    return parser.parse_args(argv)


def main(argv: Sequence[str] | None = None) -> int:
    args = parse_args(argv)
    import torch

    emit(machine_record(torch.device("cpu")))
    with tempfile.TemporaryDirectory(prefix="agrl-startup-") as folder:
        environment = {**os.environ, "AGRL_COMPILE_CACHE": str(Path(folder) / "compiled")}
        empty = first_iteration_seconds(Path(folder) / "run-empty", environment)
        warm = [first_iteration_seconds(Path(folder) / f"run-{index}", environment) for index in range(args.repeats)]
        for cache, seconds, runs in (("empty", empty, 1), ("warm", statistics.median(warm), len(warm))):
            emit({"name": "train_first_iteration_seconds", "value": round(seconds, 2), "unit": "s",
                  "compile_cache": cache, "runs": runs})
        probe = VECTOR_ENV_PROBE.format(rows=args.rows)
        subprocess.run([sys.executable, "-c", probe], env=environment, check=True, capture_output=True)  # compiles
        output = subprocess.run([sys.executable, "-c", probe], env=environment, check=True, capture_output=True,
                                text=True).stdout.split()
        first, speed, compiled = float(output[-3]), float(output[-2]), output[-1] == "True"
        emit({"name": "gym_vector_env_start_seconds", "value": round(first, 2), "unit": "s", "batch": args.rows,
              "compiled": compiled, "compile_cache": "warm"})
        emit({"name": "gym_vector_env_decisions_per_second", "value": round(speed), "unit": "decisions/s",
              "batch": args.rows, "compiled": compiled, "compile_cache": "warm", "defaults": True})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
