"""``python -m benchmarks.make_train``: ``make train`` as a user meets it on a new machine, one JSON line per timed
command (as ``benchmarks.bench``).

Clones this checkout's last commit into a temporary folder and gives it compile caches of its own, empty
(``AGRL_COMPILE_CACHE``, ``TORCHINDUCTOR_CACHE_DIR``), as a machine that never ran agrl has. Then, one command at a
time, each timed from outside:

- ``make_install_wall_seconds``: ``make install`` (the virtualenv, the packages, from pip's cache where it has
  them, and ``make compile``: make train's compilations made ahead);
- then ``--repeats`` rounds of the arms named in ``--arms``, in turn:

  - ``compile_cache=install``: both caches emptied, ``make compile`` (``make_compile_wall_seconds``, the part of
    ``make install`` that compiles), then ``make train``: a fresh clone's first run after its install;
  - ``compile_cache=empty``: both caches emptied, then ``make train``, which compiles in its own run, as every
    first run did before ``make install`` compiled ahead;
  - ``compile_cache=warm``: ``make train`` again with what the caches hold.

Each ``make_train_wall_seconds`` line also gives the run's iterations, its seconds of training, its evaluation's
success and instructions, and ``shipped_agent``: whether its actor and critic are ``agrl/baselines/fixed_baseline.pt``
bit for bit. Run it alone on an otherwise idle machine: on 2 cores the install takes about 1.5 minutes and a round of
the default arms about 3.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

import torch

from agrl.cli import positive_int
from agrl.rl.checkpoint import load_checkpoint
from benchmarks.bench import emit, machine_record

REPOSITORY = Path(__file__).resolve().parents[1]
#: The shipped agent ``make train`` reproduces, relative to the repository.
SHIPPED_AGENT = Path("agrl/baselines/fixed_baseline.pt")
ARMS = ("install", "empty", "warm")


def same_agent(first: Path, second: Path) -> bool:
    """Whether two agent files (checkpoints or shipped agents) hold the same actor and critic, tensor by tensor."""
    a, b = (load_checkpoint(path, required=("actor", "critic")) for path in (first, second))
    return all(a[part].keys() == b[part].keys() and all(torch.equal(a[part][name], b[part][name]) for name in a[part])
               for part in ("actor", "critic"))


def run_summary(output: str) -> dict:
    """The evaluation summary ``python -m agrl.train`` prints as JSON on its last line."""
    return json.loads(output.strip().splitlines()[-1])


def timed(command: Sequence[str], folder: Path, environment: dict[str, str]) -> tuple[float, str]:
    """Seconds of ``command`` run in ``folder``, and its output; its output is raised with it if it fails."""
    start = time.perf_counter()
    completed = subprocess.run(command, cwd=folder, env=environment, capture_output=True, text=True)
    seconds = time.perf_counter() - start
    if completed.returncode != 0:
        raise RuntimeError(f"{' '.join(command)} failed (exit {completed.returncode}):\n{completed.stdout[-4000:]}"
                           f"\n{completed.stderr[-4000:]}")
    return seconds, completed.stdout


def empty(caches: Sequence[Path]) -> None:
    for cache in caches:
        shutil.rmtree(cache, ignore_errors=True)
        cache.mkdir(parents=True)


def parse_args(argv: Sequence[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.make_train", description=__doc__.split("\n\n")[0])
    parser.add_argument("--arms", nargs="+", choices=ARMS, default=["install", "empty"],
                        help="what the caches hold before each make train, in turn (default: install empty)")
    parser.add_argument("--repeats", type=positive_int, default=1, help="rounds of the arms (default 1)")
    parser.add_argument("--keep", action="store_true", help="keep the clone and its caches (printed on stderr)")
    return parser.parse_args(argv)


def main(argv: Sequence[str] | None = None) -> int:
    args = parse_args(argv)
    emit(machine_record(torch.device("cpu")))
    folder = Path(tempfile.mkdtemp(prefix="agrl-make-train-"))
    try:
        clone = folder / "agrl"
        subprocess.run(["git", "clone", "-q", str(REPOSITORY), str(clone)], check=True)
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=clone, check=True, capture_output=True,
                                text=True).stdout.strip()
        caches = (folder / "compiled", folder / "torchinductor")
        environment = {**os.environ, "AGRL_COMPILE_CACHE": str(caches[0]), "TORCHINDUCTOR_CACHE_DIR": str(caches[1])}
        empty(caches)
        seconds, _ = timed(["make", "install"], clone, environment)
        emit({"name": "make_install_wall_seconds", "value": round(seconds, 2), "unit": "s", "commit": commit})
        for _ in range(args.repeats):
            for arm in args.arms:
                if arm != "warm":
                    empty(caches)
                if arm == "install":
                    seconds, _ = timed(["make", "compile"], clone, environment)
                    emit({"name": "make_compile_wall_seconds", "value": round(seconds, 2), "unit": "s",
                          "commit": commit})
                seconds, output = timed(["make", "train"], clone, environment)
                summary = run_summary(output)
                checkpoint = max((clone / "runs/fixed/baseline").glob("*/checkpoints/latest.pt"),
                                 key=lambda path: path.stat().st_mtime)
                emit({"name": "make_train_wall_seconds", "compile_cache": arm,
                      "cpu_path": summary["machine"]["cpu_capability"].lower(), "value": round(seconds, 2),
                      "unit": "s", "commit": commit, "iterations": summary["iterations"],
                      "training_s": summary["training_wall_time_s"], "success_rate": summary["success_rate"],
                      "instructions_per_episode": round(summary["instructions_per_episode"], 3),
                      "shipped_agent": same_agent(checkpoint, clone / SHIPPED_AGENT)})
    finally:
        if args.keep:
            print(f"kept: {folder}", file=sys.stderr)
        else:
            shutil.rmtree(folder, ignore_errors=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
