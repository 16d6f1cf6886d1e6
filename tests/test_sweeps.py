"""Sweeps beyond one process: Hydra's joblib and submitit launchers run real training jobs."""

from __future__ import annotations

import json

import pytest
import yaml

LAUNCHERS = ("joblib", "submitit_local")


@pytest.fixture(scope="module")
def sweeps(run_cli, tiny_args, tmp_path_factory):
    """A two-seed sweep of tiny runs through each launcher, both sweeps at once: {launcher: (sweep directory,
    CompletedProcess)}."""
    folder = tmp_path_factory.mktemp("sweeps")
    jobs = {}
    for launcher in LAUNCHERS:
        extra = ["hydra.launcher.n_jobs=2"] if launcher == "joblib" else ["hydra.launcher.timeout_min=10"]
        jobs[launcher] = ("train", "-m", f"hydra/launcher={launcher}", *extra,
                          *[arg for arg in tiny_args({"ppo.total_frames": 512, "eval.episodes": 4})
                            if not arg.startswith("seed=")],
                          "seed=0,1", f"hydra.sweep.dir={folder / launcher}", "hydra.sweep.subdir=seed_${seed}")
    results = run_cli.batch(jobs, timeout=600)
    return {launcher: (folder / launcher, results[launcher]) for launcher in LAUNCHERS}


@pytest.mark.parametrize("launcher", LAUNCHERS)
def test_launcher_runs_every_job_of_a_sweep(sweeps, launcher):
    sweep, result = sweeps[launcher]
    assert result.returncode == 0, result.stderr[-3000:]
    summaries = {path.parent.parent.name: json.loads(path.read_text()) for path in sweep.glob("*/eval/eval.json")}
    # One run directory per job (subdir = the job's overrides), each trained and evaluated with its own seed.
    assert sorted(summaries) == ["seed_0", "seed_1"]
    assert [summaries[name]["seed"] for name in ("seed_0", "seed_1")] == [0, 1]
    assert all(summary["decisions_trained"] == 512 and summary["episodes"] == 4 for summary in summaries.values())


@pytest.mark.slow
def test_a_recipe_search_runs_optuna_trials_and_reports_the_best(run_cli, tiny_args, tmp_path):
    """+experiment=recipe_search through Hydra's Optuna sweeper (the `search` extra): three tiny trials, each
    returning its search objective, and the study's best among them."""
    pytest.importorskip("hydra_plugins.hydra_optuna_sweeper")
    sweep = tmp_path / "search"
    # A target (which finetune needs) that the tiny runs, without periodic evaluations, never reach: each trial
    # ends on its frame budget whatever finetune.iterations the sampler draws.
    arguments = [arg for arg in tiny_args({"ppo.total_frames": 512, "eval.episodes": 4, "target_success": 0.5})
                 if not arg.startswith(("ppo.minibatch_size=", "ppo.epochs="))]
    result = run_cli("train", "+experiment=recipe_search", "hydra.sweeper.n_trials=3", f"hydra.sweep.dir={sweep}",
                     "ppo.minibatch_size=choice(128,256)", *arguments, "-m", timeout=600)
    assert result.returncode == 0, result.stderr[-3000:]
    objectives = {path.parent.parent.name: json.loads(path.read_text())["search_objective"]
                  for path in sweep.glob("trial_*/eval/eval.json")}
    assert sorted(objectives) == ["trial_0", "trial_1", "trial_2"]
    best = yaml.safe_load((sweep / "optimization_results.yaml").read_text())
    assert best["best_value"] == pytest.approx(min(objectives.values()))
    assert set(best["best_params"]) == {"ppo.learning_rate", "ppo.epochs", "ppo.minibatch_size", "agent.actor_hidden",
                                        "agent.critic_hidden", "reward.switch_cost", "finetune.iterations",
                                        "finetune.switch_cost", "finetune.learning_rate"}
