"""``python -m agrl.bench_reuse``: the cost of one policy-reuse relabelling (Algorithm 1), one JSON object per line.

Builds the reuse trainer of a task (the project's defaults, the shipped baseline as B), collects one
batch with the agent Z (untrained, or the actor of ``--checkpoint``), then times
:meth:`agrl.rl.reuse.PolicyReuseTransform.relabel` on that batch for each ``--candidates`` count,
with the selection factor reset to ``--selection-factor`` before every call. This is the work the
replay buffer's ``extend`` does in one training iteration (``time/reuse_seconds`` in a run).

Every line has ``name``, ``value`` (median seconds over ``--repeats`` calls after one warm-up call)
and ``unit``, plus the median process CPU seconds (``cpu_seconds``: comparable on a loaded machine with
``--threads 1``), the rows the relabelling simulated (``simulated_row_decisions``, one per row and decision:
its cost, independent of the load), the episodes selected and relabelled and the rows stored. The first line is the
machine (see :mod:`agrl.bench`).

Examples::

    python -m agrl.bench_reuse                                   # uniform 50 m/s, first batch, 8/16/32 candidates
    python -m agrl.bench_reuse --checkpoint runs/.../checkpoints/latest.pt --selection-factor 0.8
    python -m agrl.bench_reuse --quick                           # smoke test (seconds)
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from collections.abc import Sequence

import torch

from agrl.bench import _positive, emit, machine_record

#: The training configs (``conf/`` beside the package, as ``python -m agrl.train`` reads them).


def parse_args(argv: Sequence[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="python -m agrl.bench_reuse",
                                     description="Seconds per policy-reuse relabelling of one collector batch.")
    parser.add_argument("overrides", nargs="*", default=None, metavar="KEY=VALUE",
                        help="Hydra overrides of the training config (default: task=uniform speed=50)")
    parser.add_argument("--candidates", type=_positive, nargs="+", default=None, metavar="N",
                        help="method.max_candidates values to time (default 8 16 32; --quick: 4 8)")
    parser.add_argument("--selection-factor", type=float, default=1.0, metavar="E",
                        help="e before each call, in [0, 1] (default 1: every episode is selected)")
    parser.add_argument("--checkpoint", default=None,
                        help="a run checkpoint whose actor and critic are Z (default: untrained Z)")
    parser.add_argument("--repeats", type=_positive, default=None, help="timed calls (default 3; --quick: 1)")
    parser.add_argument("--threads", type=_positive, default=None, help="torch.set_num_threads")
    parser.add_argument("--quick", action="store_true",
                        help="smoke test: 64 aircraft x 16 decisions, eager simulator with a 0.1 s step")
    args = parser.parse_args(argv)
    if not 0.0 <= args.selection_factor <= 1.0:
        parser.error(f"--selection-factor={args.selection_factor} is not allowed: between 0 and 1")
    args.candidates = args.candidates or ([4, 8] if args.quick else [8, 16, 32])
    args.repeats = args.repeats or (1 if args.quick else 3)
    overrides = list(args.overrides or ["task=uniform", "speed=50"])
    if args.quick:
        overrides += ["ppo.num_envs=64", "ppo.steps_per_env=16", "eval.periodic_episodes=16",
                      "simulation.compile=false", "simulation.integration_step=0.1"]
    args.overrides = [*overrides, "method=reuse", "progress=false"]
    return args


def main(argv: Sequence[str] | None = None) -> int:
    args = parse_args(argv)
    if args.threads is not None:
        torch.set_num_threads(args.threads)
    from agrl.config import compose_config, load_config
    from agrl.rl.checkpoint import load_checkpoint, load_module_state
    from agrl.rl.reuse import candidate_steps
    from agrl.rl.trainer import Trainer

    config = load_config(compose_config(*args.overrides))
    with tempfile.TemporaryDirectory() as run_dir:
        trainer = Trainer(config, run_dir)
        emit(machine_record(trainer.device))
        if args.checkpoint:
            payload = load_checkpoint(args.checkpoint, required=("actor", "critic"))
            load_module_state(trainer.actor, payload["actor"], args.checkpoint, "actor")
            load_module_state(trainer.critic, payload["critic"], args.checkpoint, "critic")
        batch = next(iter(trainer.collector))
        trainer.collector.shutdown()
        with torch.no_grad():
            rows = trainer.advantage(batch).reshape(-1)
        transform = trainer.reuse
        budget = trainer.params.max_decisions
        # Count the rows the relabelling simulates: its cost, independent of the machine's load.
        simulated = [0]
        simulator = trainer.env.simulator

        def counting_simulator(aircraft_state, *args, **kwargs):
            simulated[0] += aircraft_state.shape[0]
            return simulator(aircraft_state, *args, **kwargs)

        trainer.env.simulator = counting_simulator
        for candidates in args.candidates:
            transform.candidates = candidate_steps(budget, config.method.candidate_stride, candidates).to(rows.device)
            timings, cpu_timings = [], []
            for call in range(args.repeats + 1):  # the first call warms up (compiles the new batch shapes)
                transform.selection_factor = args.selection_factor
                simulated[0] = 0
                start, cpu_start = time.perf_counter(), time.process_time()
                stored = transform.relabel(rows)
                if call:
                    timings.append(time.perf_counter() - start)
                    cpu_timings.append(time.process_time() - cpu_start)
            statistics_ = transform.last_statistics()
            emit({
                "name": "reuse_relabel",
                "value": round(statistics.median(timings), 3),
                "unit": "s per batch",
                "cpu_seconds": round(statistics.median(cpu_timings), 3),
                "simulated_row_decisions": simulated[0],
                "candidates": int(transform.candidates.numel()),
                "selection_factor": args.selection_factor,
                "batch_rows": rows.numel(),
                "episodes_selected": statistics_["train/reuse_episodes_selected"],
                "episodes_relabelled": statistics_["train/reuse_episodes_relabelled"],
                "rows_stored": stored.numel(),
                "reuse_fraction": round(statistics_["train/reuse_fraction"], 4),
                "z": args.checkpoint or "untrained",
                "overrides": " ".join(args.overrides),
            })
    return 0


if __name__ == "__main__":
    sys.exit(main())
