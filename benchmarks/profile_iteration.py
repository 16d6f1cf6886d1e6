"""Where one PPO iteration's time goes: ``python -m benchmarks.profile_iteration [OVERRIDE ...]``.

Builds the ``Trainer`` that ``python -m agrl.train OVERRIDE ...`` would (in a temporary folder), runs ``--warmup``
iterations (compilation, caches), times ``--iterations`` more, then profiles as many with cProfile, collection and
update each on its own. For each phase it prints its seconds per iteration, unprofiled and profiled, and the
``--top`` functions by cumulative time, as a Markdown table with each one's share of the phase's profiled time.
The profiler inflates Python's part of the time: read the shares, not the seconds.

    python -m benchmarks.profile_iteration +experiment=switch_schedule curriculum.enabled=false   # make train's shape
"""

from __future__ import annotations

import argparse
import cProfile
import pstats
import statistics
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

from benchmarks import torchrl_logs_to_stderr

PHASES = ("collection", "update")


def _where(key: tuple[str, int, str]) -> str:
    """A function as ``path:line(name)``, the path's last three parts (``agrl/rl/trainer.py``)."""
    path, line, name = key
    if path == "~":  # a built-in
        return name
    return f"{'/'.join(Path(path).parts[-3:])}:{line}({name})"


def top_functions(profile: cProfile.Profile, count: int) -> list[tuple[str, int, float]]:
    """The ``count`` functions with the most cumulative time: ``(where, calls, share of the profiled time)``."""
    stats = pstats.Stats(profile).stats
    # The profiled time: the sum of every function's own time (at least the outermost call's cumulative time, which
    # the profiler's rounding can put a little above that sum).
    total = max(sum(own for _, _, own, _, _ in stats.values()), max(entry[3] for entry in stats.values()), 1e-9)
    ranked = sorted(stats.items(), key=lambda item: item[1][3], reverse=True)[:count]
    return [(_where(key), calls, cumulative / total) for key, (_, calls, _, cumulative, _) in ranked]


def profile_iteration(overrides: Sequence[str], warmup: int, iterations: int) -> dict:
    """``{phase: {"seconds": median unprofiled s, "profiled_seconds": mean profiled s, "profile": Profile}}``."""
    from agrl.config import compose_config, load_config
    from agrl.rl.trainer import Trainer

    config = load_config(compose_config(*overrides, "progress=false"))
    plain = {phase: [] for phase in PHASES}
    profiles = {phase: cProfile.Profile() for phase in PHASES}
    with tempfile.TemporaryDirectory() as folder:
        trainer = Trainer(config, Path(folder))
        batches = iter(trainer.collector)
        for _ in range(warmup):
            trainer.learn(next(batches))
        for _ in range(iterations):
            start = time.perf_counter()
            data = next(batches)
            middle = time.perf_counter()
            trainer.learn(data)
            plain["collection"].append(middle - start)
            plain["update"].append(time.perf_counter() - middle)
        profiled = {phase: 0.0 for phase in PHASES}
        for _ in range(iterations):
            start = time.perf_counter()
            with profiles["collection"]:
                data = next(batches)
            middle = time.perf_counter()
            with profiles["update"]:
                trainer.learn(data)
            profiled["collection"] += middle - start
            profiled["update"] += time.perf_counter() - middle
        trainer.collector.shutdown()
    return {phase: {"seconds": statistics.median(plain[phase]), "profiled_seconds": profiled[phase] / iterations,
                    "profile": profiles[phase]} for phase in PHASES}


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.profile_iteration",
                                     description=__doc__.splitlines()[0])
    parser.add_argument("overrides", nargs="*", help="Hydra overrides, as for python -m agrl.train")
    parser.add_argument("--warmup", type=int, default=3, help="iterations before timing (compilation, caches)")
    parser.add_argument("--iterations", type=int, default=5, help="timed, then profiled, iterations (each)")
    parser.add_argument("--top", type=int, default=25, help="functions listed per phase")
    args = parser.parse_args(argv)
    for name in ("warmup", "iterations", "top"):
        if getattr(args, name) < 1:
            parser.error(f"--{name}={getattr(args, name)} is not allowed: a positive integer")
    torchrl_logs_to_stderr()  # stdout: the tables
    phases = profile_iteration(args.overrides, args.warmup, args.iterations)
    print(f"overrides: {' '.join(args.overrides) or '(the defaults)'}")
    for phase, result in phases.items():
        print(f"\n{phase}: {result['seconds']:.3f} s per iteration (median of {args.iterations}), "
              f"{result['profiled_seconds']:.3f} s profiled\n")
        print("| function | calls | share of profiled time |\n|---|---:|---:|")
        for where, calls, share in top_functions(result["profile"], args.top):
            print(f"| `{where}` | {calls} | {100 * share:.0f} % |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
