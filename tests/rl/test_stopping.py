"""Why a run stops (agrl.rl.stopping): budgets, the fine-tune's iterations, a (confirmed) target."""

from __future__ import annotations

import pytest

from agrl.rl.run_state import Counters
from agrl.rl.stopping import budget_spent, target_reached


@pytest.fixture(scope="module")
def config(compose_train):
    return compose_train("ppo.total_frames=1000", "ppo.max_minutes=1", "finetune.iterations=5",
                         "finetune.switch_cost=0.3", "target_success=0.9", "eval.confirm_episodes=0")


def test_budgets_in_order_frames_minutes_then_the_finetune(config):
    assert budget_spent(config, Counters(iteration=3, frames=999, wall_time=59.0)) is None
    assert budget_spent(config, Counters(frames=1000)) == "reached ppo.total_frames=1000"
    assert budget_spent(config, Counters(wall_time=60.0)) == "reached ppo.max_minutes=1.0"
    assert budget_spent(config, Counters(iteration=9, finetune_from=5)) is None
    assert budget_spent(config, Counters(iteration=10, finetune_from=5)) == (
        "fine-tuned for finetune.iterations=5 at switch cost 0.3")


def test_the_target_reads_the_periodic_or_the_confirming_evaluation(config, compose_train):
    assert target_reached(config, {}) is None
    assert target_reached(config, {"eval/success_rate": 0.89}) is None
    assert target_reached(config, {"eval/success_rate": 0.9}) == "periodic evaluation reached target_success=0.9"
    confirming = compose_train("target_success=0.9", "eval.confirm_episodes=100")
    assert target_reached(confirming, {"eval/success_rate": 1.0}) is None
    assert target_reached(confirming, {"eval/success_rate": 1.0, "eval/confirm_success_rate": 0.95}) == (
        "periodic evaluation reached target_success=0.9, confirmed on 100 other episodes (0.9500)")
