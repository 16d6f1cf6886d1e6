"""Today's compiled simulator, ms per decision at 2, 64 and 1024 rows, one thread. (docs/benchmarks.md, 2026-12-02 later morning)."""
import time, torch, sys
from agrl.config import guidance_parameters
from agrl.bench import _inputs
import agrl.core.simulation as S
torch.set_num_threads(1)
params = guidance_parameters(compile=True)
sim = S.DecisionSimulator(params.simulation, params.maneuvers.controls("cpu"), compile=True)
def t(fn, n=50):
    fn(); fn()
    s = time.perf_counter()
    for _ in range(n): fn()
    return (time.perf_counter() - s) / n
for batch in [2, 64, 1024]:
    inputs = _inputs(params, batch, torch.device("cpu"))
    with torch.no_grad():
        print("batch", batch, "per decision ms", 1e3 * t(lambda: sim(*inputs)))
