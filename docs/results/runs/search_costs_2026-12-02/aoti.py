"""An AOTInductor simulator against torch.compile, us per call of 10 integration steps. (docs/benchmarks.md, 2026-12-02 later morning)."""
import time, torch, sys, os
from agrl.config import guidance_parameters
from agrl.bench import _inputs
import agrl.core.simulation as S
from agrl.core.aircraft import AircraftState
from agrl.core.destinations import DestinationState
torch.set_num_threads(1)
params = guidance_parameters(compile=True)
controls = params.maneuvers.controls("cpu")
P = params.simulation
BODY = int(sys.argv[1]) if len(sys.argv) > 1 else 10

class M(torch.nn.Module):
    def forward(self, a0,a1,a2,a3,a4,a5,a6,d0,d1,d2,d3, speed, turn, axial, normal, direction, active, outcome):
        aircraft, destination, active, outcome = S._substeps(AircraftState(a0,a1,a2,a3,a4,a5,a6), DestinationState(d0,d1,d2,d3), speed, turn, axial, normal, direction, active, outcome, P, BODY)
        return (*aircraft, *destination, active, outcome)

def args_of(inputs):
    aircraft_state, destination_state, speed, turn, action = inputs
    a = [f.contiguous() for f in aircraft_state.unbind(-1)]
    d = [f.contiguous() for f in destination_state.unbind(-1)]
    active = torch.ones(action.shape, dtype=torch.bool)
    outcome = torch.zeros(action.shape, dtype=torch.int64)
    return (*a, *d, speed.contiguous(), turn.contiguous(), controls.axial_excess[action], controls.normal_load[action], controls.turn_direction[action], active, outcome)

inputs = _inputs(params, 64, torch.device("cpu"))
ex_args = args_of(inputs)
batch = torch.export.Dim("batch", min=2, max=1 << 20)
shapes = tuple({0: batch} for _ in ex_args)
s0 = time.perf_counter()
ep = torch.export.export(M(), ex_args, dynamic_shapes=shapes)
path = torch._inductor.aoti_compile_and_package(ep, package_path="/tmp/scratch/sim.pt2")
print("aoti compile s", time.perf_counter() - s0)
runner = torch._inductor.aoti_load_package(path)
sim = S.DecisionSimulator(P, controls, compile=True)
def t(fn, n=200):
    fn(); fn()
    s = time.perf_counter()
    for _ in range(n): fn()
    return (time.perf_counter() - s) / n
for b in [3, 64, 1024]:
    args = args_of(_inputs(params, b, torch.device("cpu")))
    with torch.no_grad():
        out = runner(*args)
        ref = sim._substeps(*args[:9], *args[11:], P, BODY) if False else None
        print("batch", b, "aoti per call us", 1e6 * t(lambda: runner(*args)),
              "compiled per call us", 1e6 * t(lambda: sim._run_substeps(AircraftState(*args[:7]), DestinationState(*args[7:11]), *args[11:])))
