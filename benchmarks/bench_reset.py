"""``python -m benchmarks.bench_reset [OVERRIDE ...]``: a collector's batch with the env's partial reset
(:meth:`agrl.envs.guidance.GuidanceEnv.maybe_reset`) against the same batch with TorchRL's (``EnvBase.maybe_reset``),
alternating in one process, one JSON line each.

Builds the ``Trainer`` that ``python -m agrl.train OVERRIDE ...`` would (in a temporary folder), trains ``--warmup``
iterations, then ``--pairs`` pairs of iterations, one collecting through each reset in turn (which goes first
alternates), every batch learnt from as in training. Each line: ``collector_batch_seconds`` (the median seconds
of collecting one batch) for ``reset=agrl`` and ``reset=torchrl``, then ``ratio_reset_agrl_over_torchrl`` (the
median of the pairs' ratios). The two resets give the same rows from the same draws
(``tests/envs/test_guidance.py``), so both collect the same kind of batches.

    python -m benchmarks.bench_reset                                           # the defaults: 512 x 64
    python -m benchmarks.bench_reset +experiment=switch_schedule curriculum.enabled=false  # make train's shape
"""

from __future__ import annotations

import argparse
import functools
import statistics
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

import torch

from agrl.cli import positive_int
from benchmarks import torchrl_logs_to_stderr
from benchmarks.bench import emit, machine_record


def bench_reset(overrides: Sequence[str], warmup: int, pairs: int) -> tuple[dict[str, list[float]], str]:
    """``{"agrl": [seconds per batch], "torchrl": [...]}``, one of each per pair, and the batch's shape
    (``<envs>x<decisions>``)."""
    from torchrl.envs import EnvBase

    from agrl.config import compose_config, load_config
    from agrl.rl.trainer import Trainer

    config = load_config(compose_config(*overrides, "progress=false"))
    seconds: dict[str, list[float]] = {"agrl": [], "torchrl": []}
    with tempfile.TemporaryDirectory() as folder:
        trainer = Trainer(config, Path(folder))
        env = trainer.env
        resets = {"agrl": None, "torchrl": functools.partial(EnvBase.maybe_reset, env)}
        batches = iter(trainer.collector)
        for _ in range(warmup):
            trainer.learn(next(batches))
        for pair in range(pairs):
            for name in sorted(resets, reverse=bool(pair % 2)):
                if resets[name] is None:
                    env.__dict__.pop("maybe_reset", None)  # the class's own
                else:
                    env.__dict__["maybe_reset"] = resets[name]
                start = time.perf_counter()
                data = next(batches)
                seconds[name].append(time.perf_counter() - start)
                trainer.learn(data)
        trainer.collector.shutdown()
    return seconds, f"{config.ppo.num_envs}x{config.ppo.steps_per_env}"


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--warmup", type=positive_int, default=3, help="iterations before timing (compilation)")
    parser.add_argument("--pairs", type=positive_int, default=10, help="timed pairs of iterations")
    parser.add_argument("overrides", nargs="*", help="Hydra overrides, as for python -m agrl.train")
    args = parser.parse_args(argv)
    torchrl_logs_to_stderr()
    emit(machine_record(torch.device("cpu")))
    seconds, shape = bench_reset(args.overrides, args.warmup, args.pairs)
    for name, values in seconds.items():
        emit({"name": "collector_batch_seconds", "reset": name, "shape": shape,
              "value": round(statistics.median(values), 4), "unit": "s/batch", "pairs": len(values),
              "each_s": [round(value, 4) for value in values]})
    ratios = [new / old for new, old in zip(seconds["agrl"], seconds["torchrl"], strict=True)]
    emit({"name": "ratio_reset_agrl_over_torchrl", "shape": shape, "value": round(statistics.median(ratios), 3),
          "unit": "x time", "range": [round(min(ratios), 3), round(max(ratios), 3)]})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
