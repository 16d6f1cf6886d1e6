"""Under Hydra's submitit launcher, a pre-empted training job is requeued and resumes by itself.

``submitit_local`` runs the job as a controller process and a task process, as Slurm would; the test sends the
task submitit's pre-emption signal (SIGUSR2) once it has trained, and the sweep must still end with the run
finished in the same directory, resumed from the checkpoint written at the signal.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import time
from pathlib import Path

import pytest

from agrl.report import read_metrics

pytestmark = pytest.mark.slow


def children(pid: int) -> list[int]:
    found = []
    for task in Path(f"/proc/{pid}/task").glob("*/children"):
        found += [int(child) for child in task.read_text().split()]
    return found


def test_a_preempted_submitit_job_is_requeued_and_resumes(tmp_path, run_cli, tiny_args):
    sweep = tmp_path / "sweep"
    iterations = 16
    command = run_cli.command(
        "train", "-m", "hydra/launcher=submitit_local", "hydra.launcher.timeout_min=10",
        "+hydra.launcher.max_num_timeout=2", f"hydra.sweep.dir={sweep}", "hydra.sweep.subdir=job",
        *tiny_args({"ppo.total_frames": 512 * iterations, "checkpoint_interval": 1000}))
    run = sweep / "job"
    with (tmp_path / "stdout").open("w") as out, (tmp_path / "stderr").open("w") as err:
        sweeper = subprocess.Popen(command, cwd=run_cli.cwd, env=run_cli.environment(), stdout=out, stderr=err)
        try:
            deadline = time.monotonic() + 240
            while len(read_metrics(run)) < 2:  # the task has trained an iteration
                assert sweeper.poll() is None, (tmp_path / "stderr").read_text()[-3000:]
                assert time.monotonic() < deadline, "the job did not train within 240 s"
                time.sleep(0.05)
            [controller] = [int(folder.name) for folder in (sweep / ".submitit").iterdir() if folder.name.isdigit()]
            [task] = children(controller)
            os.kill(task, signal.SIGUSR2)  # what submitit's controller (or Slurm) sends before the end
            assert sweeper.wait(timeout=240) == 0, (tmp_path / "stderr").read_text()[-3000:]
        finally:
            if sweeper.poll() is None:
                sweeper.kill()
                sweeper.wait()
    log = (run / "train.log").read_text()
    assert "stopped by SIGUSR2: saved the last completed iteration" in log, log[-3000:]
    assert f"{run} was pre-empted: resuming it from its last checkpoint" in log, log[-3000:]
    assert json.loads((run / "eval" / "eval.json").read_text())["iterations"] == iterations
    assert not (run / "checkpoints" / "preempted.json").exists()
