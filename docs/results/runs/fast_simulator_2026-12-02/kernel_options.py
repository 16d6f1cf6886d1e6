"""Time one decision of the fused simulator under given inductor options (docs/benchmarks.md, 2026-12-02 evening).

    python kernel_options.py '{}'                                                   # inductor's defaults (before)
    python kernel_options.py '{"cpp.min_chunk_size": 1}'
    python kernel_options.py '{"cpp.min_chunk_size": 1, "max_fusion_size": 100000}'  # agrl's options now
    python kernel_options.py '{}' --threads 1

Prints the compilation time of the first two batch sizes (the collector's 512, then 4 648 rows, which makes the
graph dynamic as the relabelling does) and milliseconds per decision at each size (median of 3 timings). Run with
a fresh TORCHINDUCTOR_CACHE_DIR for cold compilation times.
"""

import argparse
import json
import statistics
import tempfile
import time

import torch

import agrl.core.simulation as simulation
from agrl.config import compose_config, load_config
from agrl.rl.trainer import Trainer

parser = argparse.ArgumentParser()
parser.add_argument("options", type=json.loads)
parser.add_argument("--threads", type=int, default=2)
args = parser.parse_args()
torch.set_num_threads(args.threads)
simulation._INDUCTOR_OPTIONS = args.options  # exactly these options, nothing of agrl's
config = load_config(compose_config("task=uniform", "speed=50", "progress=false", "ppo.num_envs=8",
                                    "simulation.compile=false"))
env = Trainer(config, tempfile.mkdtemp()).env
start = env.reset()
simulator = simulation.DecisionSimulator(env.simulator.params, env.simulator.controls, compile=True)
generator = torch.Generator().manual_seed(0)
sizes = (512, 4648, 100, 700, 4096, 16384)
inputs = {}
for rows in sizes:
    aircraft = start["aircraft_state"][:1].repeat(rows, 1)
    aircraft = aircraft + 0.01 * torch.randn(aircraft.shape, generator=generator)
    inputs[rows] = (aircraft, start["destination_state"][:1].repeat(rows, 1), torch.full((rows,), 50.0),
                    torch.zeros(rows), torch.randint(0, 7, (rows,), generator=generator))
began = time.perf_counter()
simulator(*inputs[512])
simulator(*inputs[4648])
result = {"options": args.options, "threads": args.threads, "compile_s": round(time.perf_counter() - began, 1)}
for rows in (512, *sizes[2:]):
    calls = max(10, 60_000 // rows)
    timings = []
    for _ in range(3):
        began = time.perf_counter()
        for _ in range(calls):
            simulator(*inputs[rows])
        timings.append((time.perf_counter() - began) / calls * 1e3)
    result[f"ms_per_decision_{rows}"] = round(statistics.median(timings), 2)
print(json.dumps(result))
