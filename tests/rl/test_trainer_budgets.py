"""The trainer's stops other than the frame budget: ``target_success`` (with and without its confirmation,
``eval.confirm_episodes``) and ``ppo.max_minutes``."""

from __future__ import annotations

import logging

import pytest

from agrl.report import read_metrics
from agrl.rl.trainer import Trainer

pytestmark = pytest.mark.usefixtures("torch_one_thread")

BUDGET_ITERATIONS = 10
#: What these runs do not read: the periodic evaluations' trajectory images, and all but 4 episodes of the final
#: evaluation (it follows the stop).
UNREAD = {"eval.trajectory_image": "false", "eval.episodes": 4}


def stop_reasons(caplog) -> list[str]:
    return [record.getMessage() for record in caplog.records if record.getMessage().startswith("training stopped:")]


def test_target_success_stops_at_the_first_periodic_evaluation_that_reaches_it(tmp_path, compose_train, tiny_args,
                                                                               caplog):
    # The shipped baseline succeeds in some of these short episodes from the start; a target of one success
    # in 32 periodic episodes is met early, long before the 10-iteration frame budget.
    target = 1 / 32
    config = compose_train(*tiny_args({"ppo.total_frames": BUDGET_ITERATIONS * 512, "eval.interval": 1,
                                       "eval.periodic_episodes": 32, "target_success": target, **UNREAD}),
                           "method=pretrained")
    caplog.set_level(logging.INFO, logger="agrl.train")
    summary = Trainer(config, tmp_path / "run").train()
    rows = read_metrics(tmp_path / "run")
    evaluations = [row["eval/success_rate"] for row in rows[1:]]  # row 0: before training, never a stop
    first = next(index for index, success in enumerate(evaluations) if success >= target) + 1
    assert first < BUDGET_ITERATIONS
    assert int(rows[-1]["iteration"]) == summary["iterations"] == first
    assert stop_reasons(caplog) == [f"training stopped: periodic evaluation reached target_success={target}"]


def test_target_success_0_never_stops_a_run(tmp_path, compose_train, tiny_args, caplog):
    config = compose_train(*tiny_args({"ppo.total_frames": 2 * 512, "eval.interval": 1, "target_success": 0,
                                       **UNREAD}), "method=pretrained")
    caplog.set_level(logging.INFO, logger="agrl.train")
    assert Trainer(config, tmp_path / "run").train()["iterations"] == 2
    assert stop_reasons(caplog) == ["training stopped: reached ppo.total_frames=1024"]


def test_max_minutes_stops_after_the_iteration_that_passes_it(tmp_path, compose_train, tiny_args, caplog):
    # 6 ms of training: the first iteration takes longer, so the run stops after it.
    config = compose_train(*tiny_args({"ppo.total_frames": BUDGET_ITERATIONS * 512, "ppo.max_minutes": 0.0001,
                                       **UNREAD}))
    caplog.set_level(logging.INFO, logger="agrl.train")
    trainer = Trainer(config, tmp_path / "run")
    summary = trainer.train()
    assert summary["iterations"] == 1 and trainer.counters.frames == 512
    assert trainer.counters.wall_time >= 60 * 0.0001
    assert stop_reasons(caplog) == ["training stopped: reached ppo.max_minutes=0.0001"]


def test_a_confirmation_that_falls_short_lets_the_run_go_on(tmp_path, compose_train, tiny_args, caplog):
    """The shipped baseline flies the one periodic episode to its end (100 %) from the start, but not every one of
    64 other episodes of at most 30 decisions: no iteration may stop the run, and each logs its confirmation."""
    config = compose_train(*tiny_args({"ppo.total_frames": 2 * 512, "eval.interval": 1, "eval.periodic_episodes": 1,
                                       "target_success": 1.0, "eval.confirm_episodes": 64, **UNREAD}),
                           "method=pretrained")
    caplog.set_level(logging.INFO, logger="agrl.train")
    assert Trainer(config, tmp_path / "run").train()["iterations"] == 2
    assert stop_reasons(caplog) == ["training stopped: reached ppo.total_frames=1024"]
    rows = read_metrics(tmp_path / "run")[1:]  # row 0: before training, never a stop
    assert [row["eval/success_rate"] for row in rows] == [1.0] * 2
    assert all(0.0 < row["eval/confirm_success_rate"] < 1.0 for row in rows)


def test_a_confirmed_target_stops_the_run_and_says_so(tmp_path, compose_train, tiny_args, caplog):
    target, confirm = 0.5, 64
    config = compose_train(*tiny_args({"ppo.total_frames": BUDGET_ITERATIONS * 512, "eval.interval": 1,
                                       "eval.periodic_episodes": 32, "target_success": target,
                                       "eval.confirm_episodes": confirm, **UNREAD}), "method=pretrained")
    caplog.set_level(logging.INFO, logger="agrl.train")
    summary = Trainer(config, tmp_path / "run").train()
    rows = read_metrics(tmp_path / "run")[1:]
    # A confirmation only where the periodic evaluation reached the target; the stop at the first that held.
    assert all(("eval/confirm_success_rate" in row) == (row["eval/success_rate"] >= target) for row in rows)
    confirmed = [row.get("eval/confirm_success_rate", 0.0) >= target for row in rows]
    first = confirmed.index(True) + 1
    assert int(rows[-1]["iteration"]) == summary["iterations"] == first < BUDGET_ITERATIONS
    [reason] = stop_reasons(caplog)
    assert reason.startswith(f"training stopped: periodic evaluation reached target_success={target}, "
                             f"confirmed on {confirm} other episodes (")
