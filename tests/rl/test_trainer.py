"""The PPO Trainer: episode statistics, same-seed determinism, exact resume and the non-finite-loss guard."""

from __future__ import annotations

import csv

import numpy as np
import pytest
import torch
from tensordict import TensorDict, TensorDictBase

from agrl.core.termination import Outcome
from agrl.rl.checkpoint import load_checkpoint
from agrl.rl.trainer import Trainer, TrainingDiverged

pytestmark = pytest.mark.usefixtures("torch_one_thread")

#: Everything a resumed run continues from (``config`` differs: it records ``resume=``).
TRAINING_STATE = ("actor", "critic", "optimizer", "carrier", "rng", "reuse")


def assert_bitwise_equal(a, b, where: str = "payload") -> None:
    """Recursive exact comparison of checkpoint contents (tensors bitwise, NaN == NaN)."""
    if isinstance(a, torch.Tensor):
        assert isinstance(b, torch.Tensor), where
        assert a.dtype == b.dtype and a.shape == b.shape, where
        if a.numel():  # compare the bytes: exact, and NaN == NaN
            a, b = a.contiguous().view(-1).view(torch.uint8), b.contiguous().view(-1).view(torch.uint8)
        assert torch.equal(a, b), f"{where} differs"
    elif isinstance(a, TensorDictBase):
        assert isinstance(b, TensorDictBase), where
        assert set(a.keys(True, True)) == set(b.keys(True, True)), where
        for key in a.keys(True, True):
            assert_bitwise_equal(a[key], b[key], f"{where}[{key}]")
    elif isinstance(a, dict):
        assert isinstance(b, dict) and set(a) == set(b), f"{where}: keys {set(a) ^ set(b)}"
        for key in a:
            assert_bitwise_equal(a[key], b[key], f"{where}[{key!r}]")
    elif isinstance(a, list | tuple):
        assert isinstance(b, list | tuple) and len(a) == len(b), where
        for index, (x, y) in enumerate(zip(a, b, strict=True)):
            assert_bitwise_equal(x, y, f"{where}[{index}]")
    elif isinstance(a, np.ndarray):
        assert np.array_equal(a, b), f"{where} differs"
    else:
        assert a == b, f"{where}: {a!r} != {b!r}"


def read_csv(path):
    with path.open(newline="") as file:
        return list(csv.DictReader(file))


# ---------------------------------------------------------------------------- episode statistics
def test_episode_statistics_counts_only_finished_rows():
    # Two envs x three steps; three rows end an episode: success, out of airspace, success.
    done = torch.tensor([[False, True, False], [True, False, True]])
    outcome = torch.tensor([[Outcome.RUNNING, Outcome.SUCCESS, Outcome.RUNNING],
                            [Outcome.OUT_OF_AIRSPACE, Outcome.RUNNING, Outcome.SUCCESS]])
    episode_return = torch.tensor([[1.0, 10.0, 99.0], [-20.0, 99.0, 40.0]])
    step_count = torch.tensor([[1, 2, 1], [4, 1, 2]])
    instruction_count = torch.tensor([[0, 1, 7], [3, 7, 2]])
    # The reward's parts per step (they sum to the reward, as the env makes them).
    parts = {
        "reward_termination": torch.tensor([[0.0, 20.0, 0.0], [-20.0, 0.0, 20.0]]),
        "reward_action_shaping": torch.tensor([[0.09, -0.08, 0.0], [0.0, 0.01, -0.01]]),
        "reward_position_shaping": torch.tensor([[0.5, 0.25, -0.25], [1.0, 0.0, 0.5]]),
        "reward_switch_cost": torch.tensor([[-0.3, 0.0, -0.3], [0.0, 0.0, -0.3]]),
    }
    reward = sum(parts.values()).unsqueeze(-1)
    data = TensorDict({"next": TensorDict({
        "done": done.unsqueeze(-1), "outcome": outcome, "episode_return": episode_return,
        "step_count": step_count, "instruction_count": instruction_count, "reward": reward, **parts,
    }, batch_size=[2, 3])}, batch_size=[2, 3])

    stats = Trainer.episode_statistics(data)
    assert stats["train/episodes"] == 3
    assert stats["train/success_rate"] == pytest.approx(2 / 3)
    assert stats["train/out_of_airspace_rate"] == pytest.approx(1 / 3)
    assert stats["train/time_out_rate"] == 0.0
    assert stats["train/episode_reward"] == pytest.approx((10.0 - 20.0 + 40.0) / 3)
    assert stats["train/decisions_per_episode"] == pytest.approx((2 + 4 + 2) / 3)
    assert stats["train/instructions_per_episode"] == pytest.approx((1 + 3 + 2) / 3)
    # Means per decision over all six transitions, finished or not.
    assert stats["train/reward_termination"] == pytest.approx(20.0 / 6)
    assert stats["train/reward_action_shaping"] == pytest.approx(0.01 / 6)
    assert stats["train/reward_position_shaping"] == pytest.approx(2.0 / 6)
    assert stats["train/reward_switch_cost"] == pytest.approx(-0.9 / 6)
    assert stats["train/reward_per_decision"] == pytest.approx((20.0 + 0.01 + 2.0 - 0.9) / 6)

    data["next", "done"] = torch.zeros_like(data["next", "done"])
    idle = Trainer.episode_statistics(data)
    assert idle["train/episodes"] == 0 and "train/success_rate" not in idle
    assert idle["train/reward_switch_cost"] == pytest.approx(-0.9 / 6)  # logged even when no episode ended


# ---------------------------------------------------------------------------- determinism
@pytest.fixture(scope="module")
def one_iteration_runs(tmp_path_factory, compose_train, tiny_args):
    """The actor after one iteration for seeds 0, 0 and 1 (separate Trainers, separate directories)."""
    actors = {}
    for name, seed in (("first", 0), ("again", 0), ("other", 1)):
        config = compose_train(*tiny_args({"seed": seed, "ppo.total_frames": 512, "eval.episodes": 4}))
        trainer = Trainer(config, tmp_path_factory.mktemp(f"seed{seed}_{name}"))
        initial = {key: value.clone() for key, value in trainer.actor.state_dict().items()}
        trainer.train()
        actors[name] = (initial, trainer.actor.state_dict())
    return actors


def test_same_seed_gives_bitwise_identical_actor(one_iteration_runs):
    initial, trained = one_iteration_runs["first"]
    assert any(not torch.equal(initial[key], trained[key]) for key in initial), "training changed nothing"
    assert_bitwise_equal(trained, one_iteration_runs["again"][1], "actor")


def test_different_seed_gives_different_actor(one_iteration_runs):
    first, other = one_iteration_runs["first"][1], one_iteration_runs["other"][1]
    assert first.keys() == other.keys()
    assert any(not torch.equal(first[key], other[key]) for key in first)


# ---------------------------------------------------------------------------- exact resume
def test_resume_matches_an_uninterrupted_run_bitwise(tmp_path, tiny_run, compose_train, tiny_args, run_cli):
    """2 iterations, then ``python -m agrl.train resume=...`` for 2 more == the shared 4-iteration run."""
    straight = load_checkpoint(tiny_run.run_dir / "checkpoints" / "latest.pt")
    half = tiny_run.iterations // 2
    run = tmp_path / "run"
    config = compose_train(*tiny_args({**tiny_run.changes, "ppo.total_frames": half * 512}))
    Trainer(config, run).train()
    assert load_checkpoint(run / "checkpoints" / "latest.pt")["counters"]["iteration"] == half

    result = run_cli("train", f"resume={run}", f"ppo.total_frames={tiny_run.changes['ppo.total_frames']}",
                     f"hydra.run.dir={tmp_path / 'resume_hydra'}")
    assert result.returncode == 0, result.stderr[-3000:]

    resumed = load_checkpoint(run / "checkpoints" / "latest.pt")  # a resumed run continues in its directory
    assert resumed["config"]["resume"] == str(run)
    for key in TRAINING_STATE:
        assert_bitwise_equal(resumed[key], straight[key], key)
    for key in ("iteration", "frames", "best_success", "curriculum_scale"):
        assert resumed["counters"][key] == straight["counters"][key], key
    assert resumed["counters"]["iteration"] == tiny_run.iterations

    # Same logged values, row by row (wall times aside).
    columns = ("iteration", "frames", "train/success_rate", "eval/success_rate",
               "train/instructions_per_episode")
    rows = [[row[c] for c in columns] for row in read_csv(run / "metrics.csv")]
    assert rows == [[row[c] for c in columns] for row in read_csv(tiny_run.run_dir / "metrics.csv")]


# ---------------------------------------------------------------------------- non-finite loss
def test_non_finite_loss_stops_training_and_keeps_the_last_good_checkpoint(
    tmp_path, compose_train, tiny_args
):
    run = tmp_path / "run"
    Trainer(compose_train(*tiny_args({"ppo.total_frames": 512, "eval.episodes": 4})), run).train()
    latest = run / "checkpoints" / "latest.pt"
    good = load_checkpoint(latest, required=("actor", "critic", "optimizer", "counters", "carrier", "rng"))
    assert good["counters"]["iteration"] == 1

    # Continue the run with one critic weight set to NaN: the collector only runs the actor, so collection
    # works, and the value targets (GAE) and therefore the PPO loss become NaN in the first update.
    trainer = Trainer(compose_train(*tiny_args({"ppo.total_frames": 1024, "eval.episodes": 4})), run,
                      resume_payload={**good, "_path": str(latest)})
    with torch.no_grad():
        next(trainer.critic.parameters()).view(-1)[0] = float("nan")
    with pytest.raises(TrainingDiverged, match=r"non-finite loss .* at iteration 2\b") as raised:
        trainer.train()
    assert "\n" not in str(raised.value)
    assert str(run / "checkpoints") in str(raised.value)

    kept = load_checkpoint(latest, required=("actor", "critic", "optimizer", "counters"))
    assert kept["counters"]["iteration"] == 1
    for network in ("actor", "critic"):
        assert all(torch.isfinite(value).all() for value in kept[network].values()), network
        assert_bitwise_equal(kept[network], good[network], network)
    assert [int(row["iteration"]) for row in read_csv(run / "metrics.csv")] == [1]
