"""torch.while_loop: one compiled call per decision (docs/benchmarks.md, 2026-12-02 later morning).
python wl.py [--cpp-wrapper] [--dynamic]"""
import time, torch, sys
from torch._higher_order_ops.while_loop import while_loop
from agrl.config import guidance_parameters
from agrl.bench import _inputs
import agrl.core.simulation as S
from agrl.core.aircraft import AircraftState
from agrl.core.destinations import DestinationState
torch.set_num_threads(1)
import torch._inductor.config as IC; IC.cpp_wrapper = "--cpp-wrapper" in sys.argv  # the third column
params = guidance_parameters(compile=True)
controls = params.maneuvers.controls("cpu")
P = params.simulation
BODY = 10  # integration steps per loop iteration

def decision(a0,a1,a2,a3,a4,a5,a6,d0,d1,d2,d3, speed, turn, axial, normal, direction, active, outcome):
    counter = torch.zeros((), dtype=torch.int64)
    def cond(i, *state):
        return i < 150 // BODY
    def body(i, a0,a1,a2,a3,a4,a5,a6,d0,d1,d2,d3, active, outcome):
        aircraft, destination, active, outcome = S._substeps(AircraftState(a0,a1,a2,a3,a4,a5,a6), DestinationState(d0,d1,d2,d3), speed, turn, axial, normal, direction, active, outcome, P, BODY)
        return tuple(x.clone() for x in (i + 1, *aircraft, *destination, active, outcome))
    return while_loop(cond, body, (counter, a0,a1,a2,a3,a4,a5,a6,d0,d1,d2,d3, active, outcome))

compiled = torch.compile(decision, dynamic="--dynamic" in sys.argv, fullgraph=True)  # --dynamic: the KeyError
def run(inputs):
    aircraft_state, destination_state, speed, turn, action = inputs
    a = [f.contiguous() for f in aircraft_state.unbind(-1)]
    d = [f.contiguous() for f in destination_state.unbind(-1)]
    active = torch.ones(action.shape, dtype=torch.bool)
    outcome = torch.zeros(action.shape, dtype=torch.int64)
    return compiled(*a, *d, speed, turn, controls.axial_excess[action], controls.normal_load[action], controls.turn_direction[action], active, outcome)

sim = S.DecisionSimulator(P, controls, compile=False)
def t(fn, n=30):
    fn(); fn()
    s = time.perf_counter()
    for _ in range(n): fn()
    return (time.perf_counter() - s) / n
s0 = time.perf_counter()
for batch in [3, 64, 1024]:
    inputs = _inputs(params, batch, torch.device("cpu"))
    with torch.no_grad():
        out = run(inputs)
        ref = sim(*inputs)
        print("compiled after", time.perf_counter() - s0)
        import math
        print("maxdiff x", (out[1] - ref.aircraft_state[:, 0]).abs().max().item(), "outcome eq", bool((out[-1] == ref.outcome).all()))
        print("batch", batch, "per decision ms", 1e3 * t(lambda: run(inputs)))
