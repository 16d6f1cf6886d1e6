"""``python -m benchmarks.bench_reuse``: the cost of one policy-reuse relabelling (Algorithm 1), one JSON line each.

Builds the reuse trainer of a task (the project's defaults, the shipped baseline as B), collects one
batch with the agent Z (untrained, or the actor of ``--checkpoint``), then times
:meth:`agrl.rl.reuse.PolicyReuseTransform.relabel` on that batch for each ``--candidates`` count,
with the selection factor reset to ``--selection-factor`` before every call. This is the work the
replay buffer's ``extend`` does in one training iteration (``time/reuse_seconds`` in a run).
With ``--iterations N`` the trainer first runs N training iterations (collection, relabelling, PPO
update; one ``reuse_training_iteration`` line each, with its relabelling's figures as training met them,
the first one's compilations included), and the timed batch is the next one, relabelled from the state
training left (e, the rows kept of episodes spanning batches): a real iteration's work rather than the
first batch's.

Every line has ``name``, ``value`` (median seconds over ``--repeats`` calls after one warm-up call)
and ``unit``, plus the median process CPU seconds (``cpu_seconds``: comparable on a loaded machine with
``--threads 1``), the rows the relabelling simulated (``simulated_row_decisions``, one per row and decision:
its cost, independent of the load), the time loop's steps (``time_loop_steps``, one simulator call each) and the
process CPU seconds spent in the simulator, the row-decisions by the size of the call's batch, the episodes selected,
searched, carried over from an earlier batch and relabelled, and the rows stored. The first line is the machine (see
:mod:`benchmarks.bench`).

Examples::

    python -m benchmarks.bench_reuse                       # uniform 50 m/s, first batch, 8/16/32 candidates
    python -m benchmarks.bench_reuse --checkpoint runs/.../checkpoints/latest.pt --selection-factor 0.8
    python -m benchmarks.bench_reuse --threads 1 --candidates 16 --iterations 5 task=uniform speed=100  # a 6th
    python -m benchmarks.bench_reuse --quick               # smoke test (seconds)
"""

from __future__ import annotations

import argparse
import copy
import statistics
import sys
import tempfile
import time
from collections.abc import Sequence

import torch

from agrl.cli import positive_int
from benchmarks import torchrl_logs_to_stderr
from benchmarks.bench import emit, machine_record

#: Upper bounds of the call sizes the row-decisions are counted by (rows per simulator call).
CALL_SIZES = (32, 256, 1024)


class SimulatorCount:
    """Simulator calls of one relabelling: calls, row-decisions, CPU seconds, and row-decisions per call size."""

    def __init__(self):
        self.calls, self.row_decisions, self.cpu_seconds, self.relabel_cpu_seconds = 0, 0, 0.0, 0.0
        bounds = (0, *CALL_SIZES)
        self.by_size = {f"{low}-{high - 1}": 0 for low, high in zip(bounds, CALL_SIZES, strict=False)}
        self.by_size[f"{CALL_SIZES[-1]}+"] = 0

    def add(self, rows: int, cpu_seconds: float) -> None:
        self.calls += 1
        self.row_decisions += rows
        self.cpu_seconds += cpu_seconds
        bucket = next((index for index, high in enumerate(CALL_SIZES) if rows < high), len(CALL_SIZES))
        self.by_size[list(self.by_size)[bucket]] += rows

    def record(self) -> dict:
        return {"simulated_row_decisions": self.row_decisions, "time_loop_steps": self.calls,
                "simulator_cpu_seconds": round(self.cpu_seconds, 3), "row_decisions_by_call_rows": self.by_size}


def _episodes(statistics_: dict[str, float]) -> dict[str, int]:
    """The relabelling's episode counts (of :meth:`PolicyReuseTransform.last_statistics`)."""
    return {f"episodes_{kind}": statistics_[f"train/reuse_episodes_{kind}"]
            for kind in ("selected", "searched", "carried", "relabelled")}


def _non_negative(text: str) -> int:
    value = int(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"{value} is not allowed: >= 0")
    return value


def parse_args(argv: Sequence[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.bench_reuse",
                                     description="Seconds per policy-reuse relabelling of one collector batch.")
    parser.add_argument("overrides", nargs="*", default=None, metavar="KEY=VALUE",
                        help="Hydra overrides of the training config (default: task=uniform speed=50)")
    parser.add_argument("--candidates", type=positive_int, nargs="+", default=None, metavar="N",
                        help="method.max_candidates values to time (default 8 16 32; --quick: 4 8)")
    parser.add_argument("--selection-factor", type=float, default=None, metavar="E",
                        help="e before each call, in [0, 1] (default 1: every episode is selected; with "
                             "--iterations, the e training reached)")
    parser.add_argument("--iterations", type=_non_negative, default=0, metavar="N",
                        help="training iterations to run before the timed batch (default 0: the first batch)")
    parser.add_argument("--checkpoint", default=None,
                        help="a run checkpoint whose actor and critic are Z (default: untrained Z)")
    parser.add_argument("--repeats", type=positive_int, default=None, help="timed calls (default 3; --quick: 1)")
    parser.add_argument("--threads", type=positive_int, default=None, help="torch.set_num_threads")
    parser.add_argument("--quick", action="store_true",
                        help="smoke test: 64 aircraft x 16 decisions, eager simulator with a 0.1 s step")
    args = parser.parse_args(argv)
    if args.selection_factor is None:
        args.selection_factor = None if args.iterations else 1.0
    elif not 0.0 <= args.selection_factor <= 1.0:
        parser.error(f"--selection-factor={args.selection_factor} is not allowed: between 0 and 1")
    args.candidates = args.candidates or ([4, 8] if args.quick else [8, 16, 32])
    args.repeats = args.repeats or (1 if args.quick else 3)
    overrides = list(args.overrides or ["task=uniform", "speed=50"])
    if args.quick:
        overrides += ["ppo.num_envs=64", "ppo.steps_per_env=16", "eval.periodic_episodes=16",
                      "simulation.compile=false", "simulation.integration_step=0.1", "simulation.max_decisions=30"]
    args.overrides = [*overrides, "method=reuse", "progress=false"]
    return args


def main(argv: Sequence[str] | None = None) -> int:
    args = parse_args(argv)
    torchrl_logs_to_stderr()
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
        transform = trainer.method.transform
        # Count the rows the relabelling simulates (its cost, independent of the machine's load), per call's size;
        # the envs' own steps (collection) call the same simulator outside the relabelling and are not counted.
        simulated = SimulatorCount()
        simulator, relabel = trainer.env.simulator, transform.relabel
        relabelling = [False]

        def counting_simulator(aircraft_state, *args, **kwargs):
            cpu_start = time.process_time()
            result = simulator(aircraft_state, *args, **kwargs)
            if relabelling[0]:
                simulated.add(aircraft_state.shape[0], time.process_time() - cpu_start)
            return result

        def counting_relabel(rows):
            relabelling[0] = True
            cpu_start = time.process_time()
            try:
                return relabel(rows)
            finally:
                relabelling[0] = False
                simulated.relabel_cpu_seconds = time.process_time() - cpu_start

        trainer.env.simulator, transform.relabel = counting_simulator, counting_relabel
        batches = iter(trainer.collector)
        for iteration in range(1, args.iterations + 1):
            simulated = SimulatorCount()
            trainer.learn(next(batches))
            trainer.counters.iteration += 1
            statistics_ = transform.last_statistics()
            emit({"name": "reuse_training_iteration", "iteration": iteration,
                  "value": round(statistics_["time/reuse_relabel_seconds"], 3), "unit": "s relabelling",
                  "cpu_seconds": round(simulated.relabel_cpu_seconds, 3), **simulated.record(),
                  "selection_factor": round(statistics_["train/e"], 5), **_episodes(statistics_)})
        batch = next(batches)
        trainer.collector.shutdown()
        with torch.no_grad():
            rows = trainer.advantage(batch).reshape(-1)
        state = copy.deepcopy(transform.state_dict())  # e, the draws and the kept rows as training left them
        budget = trainer.params.max_decisions
        for candidates in args.candidates:
            transform.candidates = candidate_steps(budget, config.method.candidate_stride, candidates).to(rows.device)
            timings, cpu_timings, first_call = [], [], 0.0
            for call in range(args.repeats + 1):  # the first call warms up (compiles the new batch shapes)
                transform.load_state_dict(copy.deepcopy(state))
                if args.selection_factor is not None:
                    transform.selection_factor = args.selection_factor
                simulated = SimulatorCount()
                start, cpu_start = time.perf_counter(), time.process_time()
                stored = counting_relabel(rows)
                if call:
                    timings.append(time.perf_counter() - start)
                    cpu_timings.append(time.process_time() - cpu_start)
                else:
                    first_call = time.perf_counter() - start
            statistics_ = transform.last_statistics()
            emit({
                "name": "reuse_relabel",
                "value": round(statistics.median(timings), 3),
                "unit": "s per batch",
                "cpu_seconds": round(statistics.median(cpu_timings), 3),
                "first_call_seconds": round(first_call, 3),  # the warm-up: compilation of new batch shapes included
                **simulated.record(),
                "candidates": int(transform.candidates.numel()),
                "iterations_before": args.iterations,
                "selection_factor": round(float(state["selection_factor"]) if args.selection_factor is None
                                          else args.selection_factor, 5),
                "batch_rows": rows.numel(),
                **_episodes(statistics_),
                "rows_stored": stored.numel(),
                "reuse_fraction": round(statistics_["train/reuse_fraction"], 4),
                "z": args.checkpoint or "untrained",
                "overrides": " ".join(args.overrides),
            })
    return 0


if __name__ == "__main__":
    sys.exit(main())
