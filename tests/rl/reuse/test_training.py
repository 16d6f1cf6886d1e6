"""Policy reuse in whole training runs (``python -m agrl.train method=reuse``), end to end, with exact resume; and
the one-line errors of a baseline that does not fit (``method=pretrained``)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import torch
from reuse_scenarios import STEADY

from agrl.rl.checkpoint import save_checkpoint
from agrl.rl.models import make_actor, make_critic

#: The hand-built scenario for a whole training run: every episode starts 5 km behind the destination.
SCENARIO_START = ["simulation.initial_state.x_range=[-5000,-5000]", "simulation.initial_state.y_range=[0,0]",
                  "simulation.initial_state.z_range=[100,100]"]


def steady_checkpoint(path: Path, observation: str | None = None) -> Path:
    """A fixed-task baseline checkpoint in the trainer's format whose actor always flies steady:
    in the hand-built scenario that reaches the destination, so relabelling happens in the run.
    ``observation`` None: a checkpoint written before ``agent.observation`` existed (relative)."""
    torch.manual_seed(0)
    actor = make_actor([16, 16], "tanh", observation=observation or "relative")
    output_layer = actor.module[0].module[-1]
    with torch.no_grad():
        output_layer.weight.zero_()
        output_layer.bias.zero_()
        output_layer.bias[STEADY] = 10.0
    agent = {"name": "small", "actor_hidden": [16, 16], "critic_hidden": [16, 16], "activation": "tanh"}
    if observation is not None:
        agent["observation"] = observation
    critic = make_critic([16, 16], "tanh", observation=observation or "relative")
    save_checkpoint({"actor": actor.state_dict(), "critic": critic.state_dict(),
                     "config": {"agent": agent, "task": {"name": "fixed"}}}, path)
    return path


@pytest.fixture(scope="module")
def steady_baseline(tmp_path_factory) -> Path:
    return steady_checkpoint(tmp_path_factory.mktemp("baseline") / "steady.pt")


def scalar_values(run_dir: Path) -> dict[str, list[float]]:
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    values: dict[str, list[float]] = {}
    for events in run_dir.rglob("events.out.tfevents.*"):
        accumulator = EventAccumulator(str(events))
        accumulator.Reload()
        for tag in accumulator.Tags()["scalars"]:
            values.setdefault(tag, []).extend(event.value for event in accumulator.Scalars(tag))
    return values


@pytest.fixture(scope="module")
def reuse_runs(run_cli, tiny_args, steady_baseline, tmp_path_factory) -> dict[str, tuple[Path, object]]:
    """Two tiny ``python -m agrl.train method=reuse`` runs at once: {name: (run directory, CompletedProcess)}.
    ``relative``: from the steady baseline; ``absolute``: Z and B both read equation 4 (agent.observation=absolute)."""
    folder = tmp_path_factory.mktemp("reuse_runs")
    absolute_baseline = steady_checkpoint(folder / "steady_absolute.pt", observation="absolute")
    args = tiny_args({"ppo.total_frames": 512, "eval.interval": 1, "eval.episodes": 8})
    runs = {"relative": folder / "reuse", "absolute": folder / "reuse_absolute"}
    results = run_cli.batch({
        "relative": ("train", "task=uniform", "speed=50", "method=reuse", f"method.baseline={steady_baseline}",
                     "method.max_candidates=4", *args, *SCENARIO_START, f"hydra.run.dir={runs['relative']}"),
        "absolute": ("train", "task=uniform", "speed=50", "method=reuse", f"method.baseline={absolute_baseline}",
                     "agent.observation=absolute", "method.max_candidates=4", *args, *SCENARIO_START,
                     f"hydra.run.dir={runs['absolute']}"),
    })
    return {name: (run_dir, results[name]) for name, run_dir in runs.items()}


def test_reuse_training_runs_end_to_end(reuse_runs):
    run_dir, result = reuse_runs["relative"]
    assert result.returncode == 0, result.stderr[-3000:]
    values = scalar_values(run_dir)
    assert {"train/e", "train/reuse_fraction"} <= set(values), sorted(values)
    assert 0 < values["train/reuse_fraction"][-1] <= 1, "the steady baseline arrives: rows are relabelled"
    assert 0 < values["train/e"][-1] < 1, "e dropped by k per selected episode"
    # PPO's clip fraction per source of rows: relabelled rows exist, Z's own rows only if not all were relabelled
    assert all(0 <= value <= 1 for value in values["loss/clip_fraction_relabelled"]), sorted(values)
    assert ("loss/clip_fraction_own" in values) == (min(values["train/reuse_fraction"]) < 1), sorted(values)
    summary = json.loads((run_dir / "eval" / "eval.json").read_text())
    assert summary["method"] == "reuse" and summary["task"] == "uniform"


def test_reuse_with_the_papers_observation_runs_end_to_end(reuse_runs, compose_evaluate, tmp_path):
    """Z and B both read equation 4 as it stands (agent.observation=absolute); B is queried in the predicted
    destination's frame, and the trained agent evaluates on its own input (agrl.evaluate's evaluation, in
    process: its command line is tested in tests/test_evaluate_cli.py)."""
    from agrl.evaluate import evaluate

    run_dir, result = reuse_runs["absolute"]
    assert result.returncode == 0, result.stderr[-3000:]
    assert 0 < scalar_values(run_dir)["train/reuse_fraction"][-1] <= 1
    evaluation = evaluate(compose_evaluate(f"checkpoint={run_dir}", "episodes=8", "trajectories=0",
                                           f"output_dir={tmp_path / 'eval'}"))
    assert evaluation["episodes"] == 8
    assert json.loads((tmp_path / "eval" / "eval.json").read_text())["episodes"] == 8


def test_pretrained_from_a_baseline_of_another_observation_is_a_one_line_error(run_cli, tiny_args, tmp_path,
                                                                               steady_baseline):
    # Refused by agrl.cli's checks before Hydra runs: in process (real processes: tests/test_train_cli.py).
    result = run_cli.checks("train", "method=pretrained", f"method.baseline={steady_baseline}",
                            "agent.observation=absolute", "agent.actor_hidden=[16,16]", "agent.critic_hidden=[16,16]",
                            *tiny_args(), f"hydra.run.dir={tmp_path / 'pretrained'}")
    assert result.returncode == 2, result.stderr[-3000:]
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and "Traceback" not in result.stderr, result.stderr
    assert lines[0].startswith("agrl.train: error:") and str(steady_baseline) in lines[0]
    assert "agent.observation=absolute" in lines[0] and "observation=relative" in lines[0]
    assert not (tmp_path / "pretrained").exists()


def test_pretrained_from_weights_that_do_not_fit_their_config_is_a_one_line_error(run_cli, tiny_args, tiny_run,
                                                                                   tmp_path):
    """Z takes the networks B's saved config names (whatever ``agent`` says); a file whose weights are of other
    shapes (edited by hand) is refused before Hydra runs, in one line."""
    import torch

    payload = torch.load(tiny_run.run_dir / "checkpoints" / "latest.pt", weights_only=True)
    payload["config"]["agent"]["actor_hidden"] = [32, 32]  # the weights stay the default [128, 128] actor's
    baseline = tmp_path / "inconsistent.pt"
    torch.save(payload, baseline)
    result = run_cli.checks("train", "method=pretrained", f"method.baseline={baseline}", *tiny_args(),
                            f"hydra.run.dir={tmp_path / 'pretrained'}")
    assert result.returncode == 2, result.stderr[-3000:]
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith("agrl.train: error:") and str(baseline) in lines[0] and "actor" in lines[0]
    assert "Traceback" not in result.stderr
    assert not (tmp_path / "pretrained").exists()


@pytest.mark.parametrize("task", [
    ("task=uniform", "speed=50"),
    # The irregular destination's random redraws, with the start-box curriculum on (the tiny runs turn it off).
    ("task=irregular", "curriculum.enabled=true", "method.use_curriculum=true", "curriculum.promotion_success=0.01"),
], ids=["uniform", "irregular+curriculum"])
def test_reuse_resume_matches_an_uninterrupted_run_bitwise(tmp_path, compose_train, tiny_args, steady_baseline,
                                                          task):
    """2 reuse iterations in a row == 1, then a resumed Trainer for 1 more (the kept rows are in the checkpoint:
    a cut with state on both sides is all a bit-for-bit resume needs)."""
    from agrl.rl.checkpoint import load_checkpoint
    from agrl.rl.trainer import Trainer

    # The final evaluation follows the last checkpoint and is not compared: 4 episodes.
    overrides = [*task, "method=reuse", f"method.baseline={steady_baseline}",
                 "method.max_candidates=4", *SCENARIO_START, "eval.episodes=4"]
    straight, half = tmp_path / "straight", tmp_path / "half"
    Trainer(compose_train(*tiny_args({"ppo.total_frames": 2 * 512}), *overrides), straight).train()
    Trainer(compose_train(*tiny_args({"ppo.total_frames": 1 * 512}), *overrides), half).train()
    first = load_checkpoint(half / "checkpoints" / "latest.pt")
    reuse = reuse_state_key(first)
    assert first[reuse]["carry"]["lengths"].sum() > 0, "episodes were carried over at the cut"
    if "curriculum.enabled=true" in task:  # resumed below the full start box
        assert first["counters"]["curriculum_scale"] < 1.0
    config = compose_train(*tiny_args({"ppo.total_frames": 2 * 512}), *overrides)
    Trainer(config, half, resume_payload=first).train()
    expected = load_checkpoint(straight / "checkpoints" / "latest.pt")
    resumed = load_checkpoint(half / "checkpoints" / "latest.pt")
    for key in ("actor", "critic", reuse):
        assert_equal_nested(resumed[key], expected[key], key)
    for key in ("iteration", "frames", "curriculum_scale"):
        assert resumed["counters"][key] == expected["counters"][key], key


def reuse_state_key(checkpoint: dict) -> str:
    """Where a checkpoint holds the transform's state: ``method_state`` (the trainer's methods), or ``reuse`` in
    checkpoints written before them."""
    return "method_state" if "method_state" in checkpoint else "reuse"


def assert_equal_nested(a, b, where: str) -> None:
    if isinstance(a, dict):
        assert isinstance(b, dict) and set(a) == set(b), where
        for key in a:
            assert_equal_nested(a[key], b[key], f"{where}[{key!r}]")
    elif isinstance(a, torch.Tensor):
        assert torch.equal(a, b), f"{where} differs"
    else:
        assert a == b, f"{where}: {a!r} != {b!r}"

