"""``python -m benchmarks.bench``: simulator throughput, one JSON object per line.

Measures environment decisions per second (one decision = the paper's 3 s at a 20 ms
integration step = 150 integration steps):

- ``reference``: the pure-Python single-environment implementation of the same
  equations (:mod:`agrl.reference`), the scalar baseline;
- ``simulator``: the batched torch simulator (:class:`agrl.core.simulation.DecisionSimulator`)
  at several batch sizes, eager and fused with ``torch.compile``, with the ratio to the
  reference;
- ``torchrl_env``: the full TorchRL ``GuidanceEnv.step_and_maybe_reset`` (simulator, reward,
  observation, TensorDict bookkeeping, partial resets: what a collector calls) at one batch size;
- ``gym_vector_env``: ``gymnasium.make_vec("agrl/Guidance-v0", num_envs=N,
  vectorization_mode="vector_entry_point")`` stepped with random numpy actions (next-step autoreset,
  numpy out) at the TorchRL env's batch, eager and compiled;
- ``gym_env``: ``gymnasium.make("agrl/Guidance-v0")`` stepped with random maneuvers and reset at the
  end of each episode (what a gymnasium training loop calls), with the ratio to the reference;
- ``evaluation``: the paper's evaluation of the shipped baseline (:func:`agrl.rl.evaluation.run_episodes`, its
  deterministic policy on its own task, fixed) on ``--eval-episodes`` episodes, as ``python -m agrl.evaluate``
  runs it: episodes per second, and the decisions they flew;
- ``guide_single`` / ``guide_batch``: microseconds per query of ``agrl.guide.Guide`` (the shipped
  baseline, from its checkpoint) for one query (``instruct``, median over start states) and per row of
  one ``instruct_batch`` call at ``--guide-batch`` rows; ``--guide-formats onnx torch_export`` adds the
  same two rows for those exports (written to a temporary folder first).

Every line has ``name``, ``value`` and ``unit``, plus fields such as ``batch``,
``compiled``, ``substeps`` and ``device``. Each figure is the median of ``--repeats``
timings after a warm-up (compiled functions are compiled during the warm-up; each
compiled batch size gets its own static-shape compilation, as a training run with a
fixed ``ppo.num_envs`` does). Threads: torch's default (``torch.get_num_threads()``) unless
``--threads`` is given; the ``machine`` line reports them and the 1-minute load average
(about 0 on an otherwise idle machine).

Examples::

    python -m benchmarks.bench                # full run (a few minutes, mostly compilation)
    python -m benchmarks.bench --quick        # smoke test: small batches, eager only
    python -m benchmarks.bench --batch-sizes 512 8192 --repeats 7 --modes compiled
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import platform
import random
import statistics
import sys
import time
from collections.abc import Callable, Sequence

import torch

from agrl.cli import positive_int
from agrl.core.initial_states import sample_initial_aircraft
from agrl.core.parameters import GuidanceParameters
from agrl.core.simulation import DecisionSimulator
from agrl.envs.gym import gym_parameters
from agrl.machine import processor_record
from agrl.reference import reference_decision

FULL_BATCH_SIZES = (1024, 4096, 16384)
QUICK_BATCH_SIZES = (64, 256)
MODES = ("eager", "compiled")
#: The benchmark task: a destination in uniform motion at 50 m/s (the destination's motion is computed
#: for every task, so the cost per decision is the same for all of them).
TASK = {"task": "uniform", "speed": 50.0}


def emit(record: dict) -> None:
    print(json.dumps(record), flush=True)


def _significant(value: float, digits: int = 4) -> float:
    if value == 0 or not math.isfinite(value):
        return value
    return round(value, max(0, digits - 1 - int(math.floor(math.log10(abs(value))))))


def _synchronize(device: torch.device) -> Callable[[], None]:
    if device.type == "cuda":
        return lambda: torch.cuda.synchronize(device)
    return lambda: None


def time_call(fn: Callable[[], object], repeats: int, min_seconds: float, warmup: int,
              sync: Callable[[], None] = lambda: None) -> tuple[float, int]:
    """Median seconds per call of ``fn`` over ``repeats`` timings of ``calls`` calls each.

    ``warmup`` untimed calls come first; ``calls`` is chosen so that one timing lasts
    at least ``min_seconds``. Returns (seconds per call, calls per timing).
    """
    for _ in range(warmup):
        fn()
    sync()
    start = time.perf_counter()
    fn()
    sync()
    single = max(time.perf_counter() - start, 1e-9)
    calls = max(1, math.ceil(min_seconds / single))
    timings = []
    for _ in range(repeats):
        start = time.perf_counter()
        for _ in range(calls):
            fn()
        sync()
        timings.append((time.perf_counter() - start) / calls)
    return statistics.median(timings), calls


def _inputs(params: GuidanceParameters, batch: int, device: torch.device, seed: int = 0):
    """Start states of the benchmark task (the training distribution) and random actions."""
    generator = torch.Generator().manual_seed(seed)
    destination = torch.tensor(params.destination.start).expand(batch, 4).clone()
    aircraft = sample_initial_aircraft(batch, params.initial_state, destination, generator)
    speed, turn_rate = params.destination.initial_motion(batch, generator, torch.device("cpu"))
    action = torch.randint(0, 7, (batch,), generator=generator)
    return tuple(tensor.to(device) for tensor in (aircraft, destination, speed, turn_rate, action))


# ---------------------------------------------------------------------------- the three measurements
def bench_reference(params: GuidanceParameters, repeats: int, min_seconds: float) -> dict:
    """Decisions per second of the pure-Python single environment (one decision per call)."""
    count = 256
    inputs = (tensor.tolist() for tensor in _inputs(params, count, torch.device("cpu")))
    cases = list(zip(*inputs, strict=True))  # (aircraft, destination, speed, turn rate, action)
    simulation, maneuvers = params.simulation, params.maneuvers
    position = [0]

    def one_decision():
        case = cases[position[0] % count]
        position[0] += 1
        return reference_decision(*case, simulation, maneuvers)

    seconds, calls = time_call(one_decision, repeats, min_seconds, warmup=16)
    substeps = [reference_decision(*case, simulation, maneuvers).substeps for case in cases]
    return {
        "name": "reference_decisions_per_second",
        "value": _significant(1.0 / seconds),
        "unit": "decisions/s",
        "batch": 1,
        "compiled": False,
        "substeps": simulation.substeps,
        "device": "cpu",
        "implementation": "pure Python (math, float64), agrl/reference.py",
        # fewer than `substeps` when some decisions ended early (success or out of the airspace)
        "mean_substeps_simulated": _significant(statistics.fmean(substeps)),
        "seconds_per_decision": _significant(seconds),
        "calls_per_timing": calls,
        "repeats": repeats,
    }


def _time_decisions(name: str, one_decision, batch: int, simulator: DecisionSimulator, params: GuidanceParameters,
                    device: torch.device, repeats: int, min_seconds: float) -> dict:
    """Time ``one_decision`` (one decision for ``batch`` rows) and report decisions per second."""
    with torch.no_grad():
        start = time.perf_counter()
        seconds, calls = time_call(one_decision, repeats, min_seconds, warmup=3 if simulator.compiled else 1,
                                   sync=_synchronize(device))
    return {
        "name": name,
        "value": _significant(batch / seconds),
        "unit": "decisions/s",
        "batch": batch,
        "compiled": simulator.compiled,  # False if torch.compile failed and it fell back to eager
        "substeps": simulator.substeps,
        "integration_step": params.simulation.integration_step,
        "device": str(device),
        "seconds_per_call": _significant(seconds),
        "calls_per_timing": calls,
        "repeats": repeats,
        "wall_seconds_with_warmup": round(time.perf_counter() - start, 1),
    }


def bench_simulator(params: GuidanceParameters, batch: int, compiled: bool, device: torch.device,
                    repeats: int, min_seconds: float) -> dict:
    """Decisions per second of :class:`DecisionSimulator` for ``batch`` rows (one decision per call)."""
    if compiled:
        torch._dynamo.reset()  # a static-shape compilation for this batch size, as in training
    simulator = DecisionSimulator(params.simulation, params.maneuvers.controls(device), compile=compiled)
    inputs = _inputs(params, batch, device)
    return _time_decisions("simulator_decisions_per_second", lambda: simulator(*inputs), batch, simulator, params,
                           device, repeats, min_seconds)


def bench_torchrl_env(params: GuidanceParameters, batch: int, compiled: bool, device: torch.device,
                      repeats: int, min_seconds: float) -> dict:
    """Decisions per second of the TorchRL ``GuidanceEnv`` stepped as a collector steps it."""
    from agrl.envs.guidance import GuidanceEnv

    if compiled:
        torch._dynamo.reset()
    env = GuidanceEnv(dataclasses.replace(params, compile=compiled), num_envs=batch, device=device, seed=0)
    state = [env.reset()]

    def one_decision():
        carrier = state[0]
        carrier["action"] = env.action_spec.rand()
        _, state[0] = env.step_and_maybe_reset(carrier)

    return _time_decisions("torchrl_env_decisions_per_second", one_decision, batch, env.simulator, params,
                           device, repeats, min_seconds)


def bench_gym_vector_env(params_task: dict, batch: int, compiled: bool, device: torch.device, repeats: int,
                         min_seconds: float) -> dict:
    """Decisions per second of the gymnasium vector env (numpy actions in, numpy results out)."""
    import gymnasium
    import numpy as np

    import agrl  # registers agrl/Guidance-v0

    if compiled:
        torch._dynamo.reset()
    envs = gymnasium.make_vec(agrl.GYM_ENV_ID, num_envs=batch, vectorization_mode="vector_entry_point",
                              compile=compiled, device=str(device), **params_task)
    envs.reset(seed=0)
    actions = np.random.default_rng(0).integers(0, 7, size=(16, batch))
    position = [0]

    def one_decision():
        position[0] += 1
        envs.step(actions[position[0] % 16])

    params = envs.params
    record = _time_decisions("gym_vector_env_decisions_per_second", one_decision, batch, envs.env.simulator, params,
                             device, repeats, min_seconds)
    envs.close()
    return record


def bench_gym_env(params_task: dict, repeats: int, min_seconds: float) -> dict:
    """Decisions per second of the single gymnasium env (random maneuvers, reset when an episode ends)."""
    import gymnasium

    import agrl  # registers agrl/Guidance-v0

    env = gymnasium.make(agrl.GYM_ENV_ID, **params_task)
    env.reset(seed=0)
    actions = [random.Random(0).randrange(7) for _ in range(1024)]
    position = [0]

    def one_decision():
        position[0] += 1
        _, _, terminated, _, _ = env.step(actions[position[0] % 1024])
        if terminated:
            env.reset()

    seconds, calls = time_call(one_decision, repeats, min_seconds, warmup=16)
    return {
        "name": "gym_env_decisions_per_second",
        "value": _significant(1.0 / seconds),
        "unit": "decisions/s",
        "batch": 1,
        "compiled": False,
        "substeps": env.unwrapped.params.simulation.substeps,
        "device": "cpu",
        "implementation": "gymnasium.make('agrl/Guidance-v0'), one row in Python floats (agrl/envs/gym.py)",
        "seconds_per_decision": _significant(seconds),
        "calls_per_timing": calls,
        "repeats": repeats,
    }


def bench_evaluation(episodes: int, compiled: bool, device: torch.device, repeats: int, min_seconds: float) -> dict:
    """Episodes per second of the shipped baseline's evaluation on its task: the same ``episodes`` every call."""
    from agrl.envs.guidance import GuidanceEnv
    from agrl.rl.evaluation import run_episodes
    from agrl.rl.models import load_agent

    actor, saved, _ = load_agent("baseline", device)
    env = GuidanceEnv.for_saved_agent(saved, episodes, device=device, seed=777, compile=compiled)
    flown = []

    def one_evaluation():
        env.set_seed(777)
        flown.append(int(run_episodes(env, actor).decisions.sum()))

    seconds, calls = time_call(one_evaluation, repeats, min_seconds, warmup=1, sync=_synchronize(device))
    return {
        "name": "evaluation_episodes_per_second",
        "value": _significant(episodes / seconds),
        "unit": "episodes/s",
        "batch": episodes,
        "compiled": compiled,
        "device": str(device),
        "agent": "baseline",
        "decisions_flown": flown[-1],
        "seconds_per_evaluation": _significant(seconds),
        "calls_per_timing": calls,
        "repeats": repeats,
    }


def bench_guide(kind: str, batch: int, repeats: int, min_seconds: float) -> list[dict]:
    """Microseconds per query of the baseline :class:`agrl.guide.Guide` loaded from ``kind``: one query, a batch."""
    import tempfile

    from agrl.guide import Guide

    with tempfile.TemporaryDirectory() as folder:
        if kind == "checkpoint":
            guide = Guide.load("baseline")
        else:
            from agrl.export import SUFFIXES, export_onnx, export_torch

            path = f"{folder}/guide{SUFFIXES[kind]}"
            (export_onnx if kind == "onnx" else export_torch)("baseline", path)
            guide = Guide.load(path)
    params = gym_parameters(**TASK)
    aircraft, destination, _, _, _ = _inputs(params, batch, torch.device("cpu"))
    last_action = torch.randint(0, 7, (batch,), generator=torch.Generator().manual_seed(1))
    aircraft, destination, last_action = aircraft.numpy(), destination.numpy(), last_action.numpy()
    rows = [(aircraft[i].tolist(), destination[i].tolist(), int(last_action[i])) for i in range(min(256, batch))]
    position = [0]

    def one_query():
        position[0] += 1
        return guide.instruct(*rows[position[0] % len(rows)])

    single, single_calls = time_call(one_query, repeats, min_seconds, warmup=64)
    batched, batch_calls = time_call(lambda: guide.instruct_batch(aircraft, destination, last_action), repeats,
                                     min_seconds, warmup=2)
    common = {"unit": "us/query", "guide": kind, "device": "cpu", "repeats": repeats}
    return [
        {"name": "guide_single_query_us", "value": _significant(single * 1e6), "batch": 1,
         "calls_per_timing": single_calls, **common},
        {"name": "guide_batch_us_per_query", "value": _significant(batched * 1e6 / batch), "batch": batch,
         "seconds_per_call": _significant(batched), "calls_per_timing": batch_calls, **common},
    ]


# ---------------------------------------------------------------------------- machine and CLI
def _ram_gib() -> float | None:
    try:
        return round(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") / 2**30, 1)
    except (ValueError, OSError, AttributeError):
        return None


def machine_record(device: torch.device) -> dict:
    load = os.getloadavg() if hasattr(os, "getloadavg") else (math.nan,) * 3
    return {
        "name": "machine",
        "value": torch.get_num_threads(),
        "unit": "torch threads",
        **processor_record(),  # the processor, torch's kernel path, torch and its threads
        "cpu_count": os.cpu_count(),
        "ram_gib": _ram_gib(),
        "python": platform.python_version(),
        "device": str(device),
        "load_average_1min": round(load[0], 2),  # ~0 on an otherwise idle machine
    }


def parse_args(argv: Sequence[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog="python -m benchmarks.bench",
        description="Guidance decisions per second (150 integration steps each); one JSON line each.",
    )
    parser.add_argument("--batch-sizes", type=positive_int, nargs="+", default=None, metavar="N",
                        help=f"simulator batch sizes (default {' '.join(map(str, FULL_BATCH_SIZES))}; "
                             f"--quick: {' '.join(map(str, QUICK_BATCH_SIZES))})")
    parser.add_argument("--env-batch", type=positive_int, default=None, metavar="N",
                        help="batch of the TorchRL env measurement (default 4096; --quick: 64)")
    parser.add_argument("--repeats", type=positive_int, default=None,
                        help="timings per measurement, the median is reported (default 5; --quick: 1)")
    parser.add_argument("--min-seconds", type=float, default=None,
                        help="minimum length of one timing (default 1.0; --quick: 0.0, a single call)")
    parser.add_argument("--modes", nargs="+", choices=MODES, default=None,
                        help="eager and/or compiled (torch.compile) simulation "
                             "(default both; --quick: eager)")
    parser.add_argument("--threads", type=positive_int, default=None,
                        help="torch.set_num_threads (default: torch's default, one per core). On a machine "
                             "that other processes keep busy, 1 gives stable figures; more threads then "
                             "wait for each other")
    parser.add_argument("--eval-episodes", type=positive_int, default=None, metavar="N",
                        help="episodes of the evaluation measurement (default 1000, the paper's; --quick: 64)")
    parser.add_argument("--guide-batch", type=positive_int, default=None, metavar="N",
                        help="rows of the guide's batched query (default 4096; --quick: 64)")
    parser.add_argument("--guide-formats", nargs="+", choices=("checkpoint", "onnx", "torch_export"),
                        default=["checkpoint"], help="guides to time (default: the baseline checkpoint)")
    parser.add_argument("--device", default="cpu", help="torch device of the batched runs (default cpu)")
    parser.add_argument("--quick", action="store_true",
                        help="smoke test: small batches, one repeat, eager only (seconds, not minutes)")
    args = parser.parse_args(argv)
    quick = args.quick
    args.batch_sizes = args.batch_sizes or list(QUICK_BATCH_SIZES if quick else FULL_BATCH_SIZES)
    args.env_batch = args.env_batch or (64 if quick else 4096)
    args.guide_batch = args.guide_batch or (64 if quick else 4096)
    args.eval_episodes = args.eval_episodes or (64 if quick else 1000)
    args.repeats = args.repeats or (1 if quick else 5)
    args.min_seconds = args.min_seconds if args.min_seconds is not None else (0.0 if quick else 1.0)
    args.modes = args.modes or (["eager"] if quick else list(MODES))
    try:
        args.device = torch.device(args.device)
    except RuntimeError as error:
        parser.error(f"--device={args.device!r} is not allowed: {error}")
    if args.device.type == "cuda" and not torch.cuda.is_available():
        parser.error(f"--device={args.device} is not allowed: CUDA is not available on this machine")
    return args


def main(argv: Sequence[str] | None = None) -> int:
    args = parse_args(argv)
    if args.threads is not None:
        torch.set_num_threads(args.threads)
    random.seed(0)
    torch.manual_seed(0)
    params = gym_parameters(**TASK)  # the training defaults (conf/), compile chosen per measurement
    device = args.device
    emit(machine_record(device))

    reference = bench_reference(params, args.repeats, args.min_seconds)
    emit(reference)
    for mode in args.modes:
        compiled = mode == "compiled"
        for batch in args.batch_sizes:
            record = bench_simulator(params, batch, compiled, device, args.repeats, args.min_seconds)
            record["speedup_vs_reference"] = _significant(record["value"] / reference["value"], 3)
            emit(record)
    targets = gym_parameters(**TASK, actions="targets")  # the autopilot flying held targets (actions=targets)
    for mode in args.modes:
        for actions, task in (("maneuvers", params), ("targets", targets)):
            record = bench_torchrl_env(task, args.env_batch, mode == "compiled", device, args.repeats,
                                       args.min_seconds)
            record["actions"] = actions
            record["speedup_vs_reference"] = _significant(record["value"] / reference["value"], 3)
            emit(record)
    for mode in args.modes:
        record = bench_gym_vector_env(TASK, args.env_batch, mode == "compiled", device, args.repeats,
                                      args.min_seconds)
        record["speedup_vs_reference"] = _significant(record["value"] / reference["value"], 3)
        emit(record)
    record = bench_gym_env(TASK, args.repeats, args.min_seconds)
    record["speedup_vs_reference"] = _significant(record["value"] / reference["value"], 3)
    emit(record)
    for mode in args.modes:
        emit(bench_evaluation(args.eval_episodes, mode == "compiled", device, args.repeats, args.min_seconds))
    for kind in args.guide_formats:
        for record in bench_guide(kind, args.guide_batch, args.repeats, args.min_seconds):
            emit(record)
    return 0


if __name__ == "__main__":
    sys.exit(main())
