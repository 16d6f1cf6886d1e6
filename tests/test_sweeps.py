"""Sweeps beyond one process: Hydra's joblib and submitit launchers run real training jobs."""

from __future__ import annotations

import json

import pytest


@pytest.mark.parametrize("launcher", ["joblib", "submitit_local"])
def test_launcher_runs_every_job_of_a_sweep(tmp_path, run_cli, tiny_args, launcher):
    sweep = tmp_path / "sweep"
    extra = ["hydra.launcher.n_jobs=2"] if launcher == "joblib" else ["hydra.launcher.timeout_min=10"]
    result = run_cli("train", "-m", f"hydra/launcher={launcher}", *extra,
                     *[arg for arg in tiny_args({"ppo.total_frames": 512, "eval.episodes": 4})
                       if not arg.startswith("seed=")],
                     "seed=0,1", f"hydra.sweep.dir={sweep}", "hydra.sweep.subdir=seed_${seed}", timeout=600)
    assert result.returncode == 0, result.stderr[-3000:]
    summaries = {path.parent.parent.name: json.loads(path.read_text()) for path in sweep.glob("*/eval/eval.json")}
    # One run directory per job (subdir = the job's overrides), each trained and evaluated with its own seed.
    assert sorted(summaries) == ["seed_0", "seed_1"]
    assert [summaries[name]["seed"] for name in ("seed_0", "seed_1")] == [0, 1]
    assert all(summary["decisions_trained"] == 512 and summary["episodes"] == 4 for summary in summaries.values())
