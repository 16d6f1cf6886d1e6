"""Shared fixtures for the training / evaluation tests.

* ``tiny_args`` builds command-line overrides for tiny training runs (32 envs x 16 decisions = 512 decisions
  per iteration, a coarse 0.3 s integration step and at most 30 decisions per episode, so that an iteration
  and an evaluation take well under a second with the eager simulator; no trajectory images but the shared
  run's).
* ``compose_train`` composes ``conf/`` in-process and validates it (``agrl.config.load_config``).
* ``run_cli`` runs ``python -m agrl.<module>`` in a subprocess (one torch thread, see below); ``run_cli.checks``
  runs only its checks before Hydra, in process (a refused command line costs no interpreter start-up).
* ``tiny_run`` is one real ``python -m agrl.train`` run of 4 iterations, shared by the whole session (its xdist
  workers too: it is trained once).
* ``paper_parameters`` is the :class:`GuidanceParameters` of ``task=fixed reward=both`` composed from ``conf/`` (the
  one source of every value; the records have no defaults): the paper's Table 1/2 values and this project's
  choices, eager. A test that needs another value uses ``dataclasses.replace`` on it; ``compose_parameters``
  composes other tasks (``compose_parameters("task=irregular", "reward=both")``).

Torch runs with one intra-op thread here (``OMP_NUM_THREADS=1`` for subprocesses, ``torch_one_thread`` in
process): with tensors this small, two OpenMP threads on a busy 2-core machine spin and wait, and a tiny run
takes three times as long.
Results are compared bitwise between processes, so both sides must use the same thread count.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

import pytest
import torch
from hypothesis import HealthCheck, settings

# Property-based tests (tests/*_inputs.py): the same examples on every run and machine, no example database
# written into the working directory, no per-example deadline (a first call imports and composes).
settings.register_profile("agrl", derandomize=True, database=None, deadline=None, print_blob=False,
                          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
settings.load_profile("agrl")

CONF_DIR = (Path(__file__).resolve().parent.parent / "conf").resolve()

#: Overrides of every tiny training run (``tiny_args`` replaces or adds keys).
TINY_OVERRIDES = {
    "ppo.num_envs": "32",
    "ppo.steps_per_env": "16",
    "ppo.minibatch_size": "128",
    "ppo.epochs": "1",
    "ppo.total_frames": "1024",
    "ppo.max_minutes": "0",
    "eval.interval": "0",
    "eval.periodic_episodes": "8",
    "eval.episodes": "16",
    "simulation.compile": "false",
    "ppo.compile_loss": "false",  # a tiny run is shorter than the loss's compilation; tests/rl/test_ppo.py compiles it
    "simulation.integration_step": "0.3",
    "simulation.max_decisions": "30",
    "checkpoint_interval": "1",
    "progress": "false",
    "curriculum.enabled": "false",
    "target_success": "0",
    "eval.confirm_episodes": "0",
    "eval.trajectory_image": "false",
}
FRAMES_PER_ITERATION = 32 * 16

#: The shared run: 4 iterations, periodic evaluation after iterations 2 and 4.
TINY_RUN_ITERATIONS = 4
TINY_RUN_CHANGES = {"ppo.total_frames": str(TINY_RUN_ITERATIONS * FRAMES_PER_ITERATION), "eval.interval": "2",
                    "eval.trajectory_image": "true"}


def _tiny_args(changes: dict[str, object] | None = None) -> list[str]:
    values = {**TINY_OVERRIDES, **{key: str(value) for key, value in (changes or {}).items()}}
    return [f"{key}={value}" for key, value in values.items()]


@pytest.fixture(scope="session")
def tiny_args():
    """``tiny_args({"seed": 1, ...})`` -> override strings for a tiny run."""
    return _tiny_args


@pytest.fixture(scope="session")
def compose_train():
    """``compose_train(*overrides)`` -> a validated ``TrainConfig`` composed from ``conf/config.yaml``."""
    from hydra import compose, initialize_config_dir

    from agrl.config import load_config

    def compose_and_load(*overrides: str):
        with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
            return load_config(compose(config_name="config", overrides=list(overrides)))

    return compose_and_load


@pytest.fixture(scope="session")
def compose_parameters():
    """``compose_parameters(*overrides)`` -> eager ``GuidanceParameters`` composed from ``conf/`` (cached)."""
    import functools

    from agrl.config import guidance_parameters

    return functools.lru_cache(maxsize=None)(guidance_parameters)


@pytest.fixture(scope="session")
def paper_parameters(compose_parameters):
    """``GuidanceParameters`` of the fixed task with the paper's reward (both shaping terms, no switch cost)."""
    return compose_parameters("task=fixed", "reward=both")


@pytest.fixture(scope="session")
def compose_evaluate():
    """``compose_evaluate(*overrides)`` -> a validated ``EvaluateConfig`` from ``conf/evaluate.yaml``."""
    from hydra import compose, initialize_config_dir

    from agrl.config import load_config

    def compose_and_load(*overrides: str):
        with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
            return load_config(compose(config_name="evaluate", overrides=list(overrides)))

    return compose_and_load


def _cli_environment() -> dict[str, str]:
    env = dict(os.environ)
    env.pop("HYDRA_FULL_ERROR", None)
    env["OMP_NUM_THREADS"] = "1"
    env["MKL_NUM_THREADS"] = "1"
    env["PYTHONUNBUFFERED"] = "1"
    return env


def _cli_command(module: str, *args: str) -> list[str]:
    # The suite's own warning policy: torchrl's 0.15 transition warnings must fail loudly.
    return [sys.executable, "-W", "error::FutureWarning", "-m", f"agrl.{module}", *args]


def _run_cli(module: str, *args: str, cwd: Path, timeout: float = 300) -> subprocess.CompletedProcess:
    return subprocess.run(_cli_command(module, *args), cwd=cwd, env=_cli_environment(), capture_output=True,
                          text=True, timeout=timeout)


def _run_at_once(commands: dict[str, list[str]], cwd: Path | dict[str, Path], env: dict[str, str] | None = None,
                 timeout: float = 300) -> dict[str, subprocess.CompletedProcess]:
    """Run several commands at once (each is mostly interpreter start-up and imports): {name: its result}.
    ``cwd`` is one folder for all, or one per name."""
    started = {}
    for name, command in commands.items():
        folder = cwd[name] if isinstance(cwd, dict) else cwd
        out, err = tempfile.TemporaryFile("w+"), tempfile.TemporaryFile("w+")
        started[name] = (command, subprocess.Popen(command, cwd=folder, env=env, stdout=out, stderr=err, text=True),
                         out, err)
    results = {}
    try:
        for name, (command, process, out, err) in started.items():
            process.wait(timeout=timeout)
            out.seek(0)
            err.seek(0)
            results[name] = subprocess.CompletedProcess(command, process.returncode, out.read(), err.read())
    finally:
        for _, process, out, err in started.values():
            if process.poll() is None:
                process.kill()
                process.wait()
            out.close()
            err.close()
    return results


def _run_cli_batch(jobs: dict[str, tuple[str, ...]], cwd: Path, timeout: float = 300):
    """Run several ``(module, *args)`` jobs of ``python -m agrl.<module>`` at once."""
    commands = {name: _cli_command(module, *args) for name, (module, *args) in jobs.items()}
    return _run_at_once(commands, cwd, _cli_environment(), timeout)


@pytest.fixture(scope="session")
def run_at_once():
    """``run_at_once({name: command}, cwd, env=None, timeout=300)`` -> {name: CompletedProcess}: the commands run
    side by side (for the benchmarks, which are not ``agrl`` entry points)."""
    return _run_at_once


#: {module: its root config}, as each ``__main__`` passes them to :func:`agrl.cli.run_checked`.
CHECKED_ENTRY_POINTS = {"train": "config", "evaluate": "evaluate"}


def _run_checks(module: str, *args: str, cwd: Path) -> subprocess.CompletedProcess:
    """What ``python -m agrl.<module> *args`` does before Hydra runs (:func:`agrl.cli.run_checked` with the module's
    config and ``check_inputs``), in this process and in ``cwd``: returncode 2 and the stderr line of a refused
    command line, or 0 and no output if the run would start (it is not started)."""
    import contextlib
    import importlib
    import io

    from agrl.cli import run_checked

    entry_point = importlib.import_module(f"agrl.{module}")
    stdout, stderr, argv = io.StringIO(), io.StringIO(), sys.argv
    sys.argv = [f"agrl.{module}", *args]
    code = 0
    try:
        with contextlib.chdir(cwd), contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr):
            run_checked(lambda: None, f"agrl.{module}", CHECKED_ENTRY_POINTS[module], entry_point.check_inputs)
    except SystemExit as exit_:
        code = exit_.code
    finally:
        sys.argv = argv
    return subprocess.CompletedProcess(["run_checked", f"agrl.{module}", *args], code, stdout.getvalue(),
                                       stderr.getvalue())


@pytest.fixture(scope="session")
def cli_workdir(tmp_path_factory) -> Path:
    """Working directory of CLI subprocesses (so nothing lands in the repository's ``runs/``)."""
    return tmp_path_factory.mktemp("cli_cwd")


@pytest.fixture(scope="session")
def run_cli(cli_workdir):
    """``run_cli("train", *overrides)`` -> CompletedProcess of ``python -m agrl.train ...``;
    ``run_cli.batch({"name": ("train", *overrides), ...})`` runs several at once (``cwd=``: in another folder)
    and returns {name: CompletedProcess}; ``run_cli.checks("train", *overrides)`` runs only the checks made before
    Hydra runs, in this process (no interpreter start-up: for the many refused command lines)."""

    def run(module: str, *args: str, timeout: float = 300) -> subprocess.CompletedProcess:
        return _run_cli(module, *args, cwd=cli_workdir, timeout=timeout)

    def batch(jobs: dict[str, tuple[str, ...]], timeout: float = 300, cwd: Path | None = None) -> dict:
        return _run_cli_batch(jobs, cwd=cwd or cli_workdir, timeout=timeout)

    def checks(module: str, *args: str) -> subprocess.CompletedProcess:
        return _run_checks(module, *args, cwd=cli_workdir)

    run.batch = batch
    run.checks = checks
    run.command = _cli_command
    run.environment = _cli_environment
    run.cwd = cli_workdir
    return run


@pytest.fixture(scope="module")
def torch_one_thread():
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


@dataclass
class TinyRun:
    run_dir: Path
    changes: dict[str, str]  # what ``tiny_args`` was given
    iterations: int
    overrides: list[str]
    stdout: str
    stderr: str


def _shared_run(tmp_path_factory, cli_workdir, name: str, changes: dict[str, str], iterations: int) -> TinyRun:
    """One real ``python -m agrl.train`` run of ``tiny_args(changes)`` per test session, not per xdist worker: the
    first worker to ask trains it under a file lock in the session's shared temporary folder (pytest-xdist's
    documented pattern) and records its result there; the others wait for the lock and read the record (a failed
    run is recorded too, and fails them the same way)."""
    import json

    from filelock import FileLock

    root = tmp_path_factory.getbasetemp()
    if os.environ.get("PYTEST_XDIST_WORKER"):
        root = root.parent  # this session's folder, shared by its workers (each has its own basetemp below it)
    folder = root / f"{name}_shared"
    record = folder / "result.json"
    with FileLock(str(root / f"{name}_shared.lock")):
        if not record.is_file():
            folder.mkdir(exist_ok=True)
            result = _run_cli("train", *_tiny_args(changes), f"hydra.run.dir={folder / 'run'}", cwd=cli_workdir)
            record.write_text(json.dumps({"returncode": result.returncode, "stdout": result.stdout,
                                          "stderr": result.stderr}))
    result = json.loads(record.read_text())
    assert result["returncode"] == 0, f"{name} failed:\n{result['stdout'][-3000:]}\n{result['stderr'][-3000:]}"
    return TinyRun(run_dir=folder / "run", changes=dict(changes), iterations=iterations,
                   overrides=_tiny_args(changes), stdout=result["stdout"], stderr=result["stderr"])


@pytest.fixture(scope="session")
def tiny_run(tmp_path_factory, cli_workdir) -> TinyRun:
    """One real ``python -m agrl.train`` run (4 iterations, seed 0); treat its directory as read-only."""
    return _shared_run(tmp_path_factory, cli_workdir, "tiny_run", TINY_RUN_CHANGES, TINY_RUN_ITERATIONS)


#: The shared run of an agent holding targets: 2 iterations, no periodic evaluation.
TINY_TARGETS_CHANGES = {"actions": "targets", "ppo.total_frames": str(2 * FRAMES_PER_ITERATION)}


@pytest.fixture(scope="session")
def tiny_targets_run(tmp_path_factory, cli_workdir) -> TinyRun:
    """One real ``python -m agrl.train actions=targets`` run (2 iterations, seed 0); treat it as read-only."""
    return _shared_run(tmp_path_factory, cli_workdir, "tiny_targets_run", TINY_TARGETS_CHANGES, 2)
