"""Imports run one way: core <- config <- envs <- rl <- entry points, with no cycles.

Every module of agrl is read with ``ast`` (imports inside functions count too) and must
import only modules of its own layer or a lower one. A new module must be given a layer here.
The benchmarks (``benchmarks/``, beside the package and not in the wheel) import agrl; agrl never imports them.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parent.parent / "agrl"

#: Layer of each module (longest matching prefix wins); lower layers never import higher ones.
LAYERS = {
    "agrl": 0,  # the package itself: version and the gymnasium registration (by name, no import)
    "agrl.baselines": 0,  # the shipped baseline's location
    "agrl.core": 0,  # pure batched torch: no Hydra, no TorchRL
    "agrl.reference": 1,  # the pure-Python one-row simulator (single gym env, test oracle, benchmark baseline)
    "agrl.rows": 1,  # the pure-Python one-row observation and reward (single gym env, single-query guide)
    "agrl.plots": 1,  # figures from plain records
    "agrl.machine": 1,  # the processor and threads a run's results were made with
    "agrl.config": 1,  # Hydra structured schemas, composition, and the core records built from them by name
    "agrl.envs": 2,  # TorchRL and gymnasium environments
    "agrl.rl": 3,  # actor-critic, PPO trainer, checkpoints, evaluation, policy reuse
    "agrl.train": 4, "agrl.evaluate": 4, "agrl.export": 4, "agrl.report": 4,  # entry points
    "agrl.guide": 4, "agrl.distill": 4, "agrl.cli": 4,  # the entry points' command-line check
    "agrl.plan": 4,  # the instruction plan of a guide (python -m agrl.plan)
}


def module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def layer_of(module: str) -> int:
    prefixes = [prefix for prefix in LAYERS if module == prefix or module.startswith(prefix + ".")]
    if not prefixes:
        raise AssertionError(f"{module} has no layer in tests/test_imports.py: give it one")
    return LAYERS[max(prefixes, key=len)]


def imported_agrl_modules(path: Path) -> set[str]:
    """The agrl modules ``path`` imports (``from agrl.x import y`` counts as ``agrl.x``)."""
    found = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names if alias.name.split(".")[0] == "agrl")
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and (node.module or "").split(".")[0] == "agrl":
            found.add(node.module)
    return found


def imports_benchmarks(path: Path) -> bool:
    """Whether ``path`` imports anything from the top-level ``benchmarks`` package."""
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import) and any(alias.name.split(".")[0] == "benchmarks" for alias in node.names):
            return True
        if isinstance(node, ast.ImportFrom) and node.level == 0 and (node.module or "").split(".")[0] == "benchmarks":
            return True
    return False


def import_graph() -> dict[str, set[str]]:
    return {module_name(path): imported_agrl_modules(path) for path in sorted(PACKAGE.rglob("*.py"))}


def test_every_module_imports_only_its_own_or_lower_layers():
    reverse = [
        f"{module} (layer {layer_of(module)}) imports {target} (layer {layer_of(target)})"
        for module, targets in import_graph().items()
        for target in sorted(targets)
        if layer_of(target) > layer_of(module)
    ]
    assert reverse == []


def test_the_package_never_imports_the_benchmarks(tmp_path):
    # The wheel ships agrl without benchmarks/: an import of them would fail in every installed copy.
    offender = tmp_path / "uses_bench.py"
    offender.write_text("def f():\n    from benchmarks.bench import emit\n    return emit\n")
    assert imports_benchmarks(offender)
    assert [module_name(path) for path in sorted(PACKAGE.rglob("*.py")) if imports_benchmarks(path)] == []


def test_no_import_cycles():
    graph = import_graph()
    # A package's __init__ is what `import agrl.x.y` runs first: an edge to agrl.x.y also reaches agrl.x,
    # unless agrl.x is the importing module's own package (already being imported by then).
    def targets(module: str) -> set[str]:
        own_packages = {".".join(module.split(".")[:length]) for length in range(1, module.count(".") + 2)}
        reached = set()
        for target in graph.get(module, ()):
            parts = target.split(".")
            reached.update(".".join(parts[:length]) for length in range(2, len(parts) + 1))
        return (reached - own_packages) & graph.keys()

    state: dict[str, str] = {}
    cycles = []

    def visit(module: str, path: list[str]) -> None:
        state[module] = "open"
        for target in sorted(targets(module)):
            if state.get(target) == "open":
                cycles.append(" -> ".join(path[path.index(target):] + [target]))
            elif target not in state:
                visit(target, path + [target])
        state[module] = "done"

    for module in sorted(graph):
        if module not in state:
            visit(module, [module])
    assert cycles == []


def test_the_checker_sees_a_reverse_import(tmp_path):
    # The rules above must be able to fail: a core module importing the trainer is caught.
    offender = tmp_path / "agrl" / "core" / "bad.py"
    offender.parent.mkdir(parents=True)
    offender.write_text("def f():\n    from agrl.rl.trainer import Trainer\n    return Trainer\n")
    assert imported_agrl_modules(offender) == {"agrl.rl.trainer"}
    assert layer_of("agrl.core.bad") < layer_of("agrl.rl.trainer")


@pytest.mark.parametrize("module", ["agrl", "agrl.config", "agrl.report", "agrl.core.simulation"])
def test_light_modules_do_not_load_torchrl(module):
    code = f"import sys, {module}; print(sorted(m for m in ('torchrl', 'tensordict') if m in sys.modules))"
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True)
    assert result.stdout.strip() == "[]"
