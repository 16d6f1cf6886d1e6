"""Training, evaluating and reusing agents that hold targets (``actions=targets``), end to end on the command line:
a checkpoint records its action set, every method trains with it, and the evaluation reads it back."""

from __future__ import annotations

import json

import pytest

from agrl.rl.checkpoint import load_checkpoint, load_latest_checkpoint


def _summary(result) -> dict:
    assert result.returncode == 0, result.stderr[-3000:]
    return json.loads(result.stdout.strip().splitlines()[-1])


def test_a_targets_run_records_its_action_set_and_carries_its_held_targets(tiny_targets_run):
    _, payload, _ = load_latest_checkpoint(tiny_targets_run.run_dir / "checkpoints" / "latest.pt",
                                           required=("actor", "config", "carrier"))
    assert payload["config"]["actions"]["name"] == "targets"
    assert payload["config"]["actions"]["headings"] == 12
    assert payload["carrier"]["held_targets"].shape == (32, 3)  # the collector's rows resume holding their targets
    summary = json.loads(tiny_targets_run.stdout.strip().splitlines()[-1])
    assert summary["episodes"] == 16 and 0 <= summary["success_rate"] <= 1


@pytest.fixture(scope="module")
def target_methods(run_cli, tiny_args, tiny_targets_run, tmp_path_factory):
    """Policy reuse and pre-training from the tiny targets agent on the uniform task, and its evaluation."""
    folder = tmp_path_factory.mktemp("target_methods")
    baseline = str(tiny_targets_run.run_dir)
    moving = ("task=uniform", "speed=50")
    return folder, run_cli.batch({
        "reuse": ("train", *tiny_args(), "actions=targets", *moving, "method=reuse", f"method.baseline={baseline}",
                  f"hydra.run.dir={folder / 'reuse'}"),
        "pretrained": ("train", *tiny_args(), "actions=targets", *moving, "method=pretrained",
                       f"method.baseline={baseline}", f"hydra.run.dir={folder / 'pretrained'}"),
        "evaluate": ("evaluate", f"checkpoint={baseline}", "episodes=32", "trajectories=2",
                     f"output_dir={folder / 'eval'}"),
    })


@pytest.mark.parametrize("method", ["reuse", "pretrained"])
def test_reuse_and_pretraining_train_an_agent_holding_targets(target_methods, method):
    folder, results = target_methods
    summary = _summary(results[method])
    assert summary["method"] == method and summary["task"] == "uniform"
    payload = load_checkpoint(folder / method / "checkpoints" / "latest.pt", required=("actor", "config"))
    assert payload["config"]["actions"]["name"] == "targets"
    assert payload["actor"]["module.0.module.0.weight"].shape[1] == 16 + 4  # geometry + held targets
    assert payload["actor"]["module.0.module.4.bias"].shape == (26,)


def test_reuse_relabels_episodes_of_an_agent_holding_targets(target_methods):
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    folder, _ = target_methods
    events = EventAccumulator(str(folder / "reuse" / "tensorboard"))
    events.Reload()
    searched = [event.value for event in events.Scalars("train/reuse_episodes_searched")]
    relabelled = [event.value for event in events.Scalars("train/reuse_episodes_relabelled")]
    assert sum(searched) > 0 and len(relabelled) == len(searched)


def test_the_evaluation_flies_a_checkpoints_own_action_set(target_methods):
    folder, results = target_methods
    summary = _summary(results["evaluate"])
    assert summary["episodes"] == 32
    assert (folder / "eval" / "eval.json").is_file() and (folder / "eval" / "trajectories.png").is_file()
