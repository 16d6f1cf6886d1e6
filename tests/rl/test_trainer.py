"""The PPO Trainer: episode statistics, same-seed determinism, exact resume and the non-finite-loss guard."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
from tensordict import TensorDictBase

from agrl.report import read_metrics
from agrl.rl.checkpoint import load_checkpoint
from agrl.rl.reuse import TRAJECTORY_KEY
from agrl.rl.trainer import Trainer, TrainingDiverged

pytestmark = pytest.mark.usefixtures("torch_one_thread")

#: Everything a resumed run continues from (``config`` differs: it records ``resume=``).
TRAINING_STATE = ("actor", "critic", "optimizer", "carrier", "rng", "method_state")


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


# ---------------------------------------------------------------------------- determinism
#: One-iteration runs: episodes of at most 8 decisions (each of the 16 collection steps then sees episodes end
#: and restart), and so a short final evaluation of 4 episodes.
ONE_ITERATION = {"ppo.total_frames": 512, "eval.episodes": 4, "simulation.max_decisions": 8}


@pytest.fixture(scope="module")
def one_iteration_runs(tmp_path_factory, compose_train, tiny_args):
    """The actor after one iteration for seeds 0, 0 and 1 (separate Trainers, separate directories)."""
    actors = {}
    for name, seed in (("first", 0), ("again", 0), ("other", 1)):
        config = compose_train(*tiny_args({**ONE_ITERATION, "seed": seed}))
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
    """2 iterations, then ``python -m agrl.train resume=...`` for 2 more == the shared 4-iteration run. The final
    evaluations, after each half's last checkpoint and not compared, fly 4 episodes (the resumed half reads the
    saved config)."""
    straight = load_checkpoint(tiny_run.run_dir / "checkpoints" / "latest.pt")
    half = tiny_run.iterations // 2
    run = tmp_path / "run"
    config = compose_train(*tiny_args({**tiny_run.changes, "ppo.total_frames": half * 512, "eval.episodes": 4}))
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
    rows = [[row.get(c) for c in columns] for row in read_metrics(run)]
    assert rows == [[row.get(c) for c in columns] for row in read_metrics(tiny_run.run_dir)]


def test_a_run_holding_targets_resumes_bitwise(tmp_path, tiny_targets_run, compose_train, tiny_args, run_cli):
    """The same for ``actions=targets`` (the collector's rows carry their held targets): 1 iteration, then a resume
    for 1 more == the shared 2-iteration run."""
    straight = load_checkpoint(tiny_targets_run.run_dir / "checkpoints" / "latest.pt")
    run = tmp_path / "run"
    Trainer(compose_train(*tiny_args({**tiny_targets_run.changes, "ppo.total_frames": 512, "eval.episodes": 4})),
            run).train()
    result = run_cli("train", f"resume={run}", f"ppo.total_frames={tiny_targets_run.changes['ppo.total_frames']}",
                     f"hydra.run.dir={tmp_path / 'resume_hydra'}")
    assert result.returncode == 0, result.stderr[-3000:]
    resumed = load_checkpoint(run / "checkpoints" / "latest.pt")
    assert resumed["counters"]["iteration"] == tiny_targets_run.iterations
    for key in TRAINING_STATE:
        assert_bitwise_equal(resumed[key], straight[key], key)


# ---------------------------------------------------------------------------- non-finite loss
def test_non_finite_loss_stops_training_and_keeps_the_last_good_checkpoint(
    tmp_path, compose_train, tiny_args
):
    run = tmp_path / "run"
    Trainer(compose_train(*tiny_args(ONE_ITERATION)), run).train()
    latest = run / "checkpoints" / "latest.pt"
    good = load_checkpoint(latest, required=("actor", "critic", "optimizer", "counters", "carrier", "rng"))
    assert good["counters"]["iteration"] == 1

    # Continue the run with one critic weight set to NaN: the collector only runs the actor, so collection
    # works, and the value targets (GAE) and therefore the PPO loss become NaN in the first update.
    trainer = Trainer(compose_train(*tiny_args({**ONE_ITERATION, "ppo.total_frames": 1024})), run,
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
    assert [int(row["iteration"]) for row in read_metrics(run)] == [1]


# ---------------------------------------------------------------------------- evaluation schedule
def test_wall_clock_evaluation_schedule(tmp_path, compose_train, tiny_args):
    config = compose_train(*tiny_args({"eval.interval_seconds": 10, "eval.interval": 3}))
    trainer = Trainer(config, tmp_path / "run")
    due = []
    for wall_time in (0.0, 4.0, 9.9, 10.0, 12.0, 35.0, 39.0, 40.0):
        trainer.counters.wall_time = wall_time
        due.append(trainer._evaluation_due({}))
    # Every 10 s of training (eval.interval is then ignored); a long iteration skips the missed slots.
    assert due == [True, False, False, True, False, True, False, True]
    assert trainer.counters.next_evaluation_time == 50.0
    trainer.collector.shutdown()


def test_iteration_evaluation_schedule(tmp_path, compose_train, tiny_args):
    trainer = Trainer(compose_train(*tiny_args({"eval.interval": 3})), tmp_path / "run")
    due = []
    for iteration in range(1, 8):
        trainer.counters.iteration = iteration
        due.append(trainer._evaluation_due({}))
    assert due == [False, False, True, False, False, True, False]
    trainer.collector.shutdown()


def test_evaluations_wait_for_training_success_on_the_full_box(tmp_path, compose_train, tiny_args):
    """``eval.min_train_success``: no periodic evaluation before the curriculum's full box and that training success;
    the schedule (every 2 iterations here) applies from then on."""
    config = compose_train(*tiny_args({"eval.interval": 2, "eval.min_train_success": 0.9, "curriculum.enabled": True}))
    trainer = Trainer(config, tmp_path / "run")
    due = []
    for iteration, scale, success in ((2, 0.5, 1.0), (4, 1.0, 0.85), (5, 1.0, 0.95), (6, 1.0, 0.9), (8, 1.0, None)):
        trainer.counters.iteration, trainer.counters.curriculum_scale = iteration, scale
        due.append(trainer._evaluation_due({} if success is None else {"train/success_rate": success}))
    assert due == [False, False, False, True, False]
    trainer.collector.shutdown()


def test_wall_clock_evaluations_wait_too_and_owe_nothing_for_the_skipped_slots(tmp_path, compose_train, tiny_args):
    """With ``eval.interval_seconds``, the evaluations skipped while waiting are not made up afterwards: one
    evaluation when the wait ends, then the next 10-s slot."""
    config = compose_train(*tiny_args({"eval.interval_seconds": 10, "eval.min_train_success": 0.9}))
    trainer = Trainer(config, tmp_path / "run")
    due = []
    for wall_time, success in ((0.0, 0.5), (12.0, 0.5), (35.0, 0.95), (36.0, 0.95), (39.0, 0.95), (40.0, 0.95)):
        trainer.counters.wall_time = wall_time
        due.append(trainer._evaluation_due({"train/success_rate": success}))
    assert due == [False, False, True, False, False, True]
    assert trainer.counters.next_evaluation_time == 50.0
    trainer.collector.shutdown()


def test_threads_setting_reaches_torch(tmp_path, compose_train, tiny_args):
    torch.set_num_threads(2)  # the fixture restores the previous count afterwards
    trainer = Trainer(compose_train(*tiny_args({"threads": 1})), tmp_path / "run")
    assert torch.get_num_threads() == 1
    trainer.collector.shutdown()
    torch.set_num_threads(2)
    trainer = Trainer(compose_train(*tiny_args({"threads": "null"})), tmp_path / "other")
    assert torch.get_num_threads() == 2  # null leaves torch's setting alone
    trainer.collector.shutdown()


def test_buffer_keeps_only_the_fields_the_update_reads(tmp_path, compose_train, tiny_args):
    trainer = Trainer(compose_train(*tiny_args({})), tmp_path / "run")
    data = next(iter(trainer.collector))
    trainer.learn(data)
    stored = set(trainer.buffer[:].keys(True, True)) - {"index"}  # "index": the buffer adds it on reading
    assert stored == {"observation", "action", "action_log_prob", "advantage", "value_target", "state_value"}
    trainer.collector.shutdown()


@pytest.mark.parametrize(("method", "numbered"), [((), False), (("method=reuse",), True)])
def test_the_collector_numbers_episodes_only_for_a_method_that_reads_them(tmp_path, compose_train, tiny_args, method,
                                                                          numbered):
    trainer = Trainer(compose_train(*tiny_args({}), *method), tmp_path / "run")
    data = next(iter(trainer.collector))
    assert (TRAJECTORY_KEY in data.keys(True)) is numbered
    assert "logits" not in data.keys()  # the sampler's batch: the update recomputes the logits it needs
    trainer.collector.shutdown()


@pytest.mark.parametrize(("target_kl", "limited"), [(0.0, False), (1e-12, True)])
def test_the_kl_limit_reaches_the_trainers_update(tmp_path, compose_train, tiny_args, target_kl, limited):
    """``ppo.target_kl`` from the config stops the trainer's update: with a tiny limit it stops early (the first
    minibatch, taken before the policy moves, always steps; the estimate of later ones can be below any limit by
    chance); without one, every epoch's minibatches step."""
    config = compose_train(*tiny_args({"ppo.target_kl": target_kl}))
    trainer = Trainer(config, tmp_path / "run")
    _, losses, _ = trainer.learn(next(iter(trainer.collector)))
    every_minibatch = config.ppo.epochs * math.ceil(config.ppo.num_envs * config.ppo.steps_per_env
                                                    / config.ppo.minibatch_size)
    if limited:
        assert 1 <= losses["minibatches"] < every_minibatch
    else:
        assert losses["minibatches"] == every_minibatch
    trainer.collector.shutdown()
