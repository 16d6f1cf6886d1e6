"""PPO pieces: the learning-rate schedule and the update's divergence guard (agrl.rl.ppo)."""

from __future__ import annotations

import pytest

from agrl.rl.ppo import annealed_learning_rate
from agrl.rl.trainer import Trainer

pytestmark = pytest.mark.usefixtures("torch_one_thread")


def test_annealed_learning_rate_is_linear_to_zero():
    assert annealed_learning_rate(5e-4, 0, 1_000) == 5e-4
    assert annealed_learning_rate(5e-4, 250, 1_000) == pytest.approx(3.75e-4)
    assert annealed_learning_rate(5e-4, 1_000, 1_000) == 0.0
    assert annealed_learning_rate(5e-4, 1_500, 1_000) == 0.0  # a resumed run past its budget


@pytest.mark.parametrize("anneal", [True, False])
def test_trainer_applies_the_schedule_each_iteration(tmp_path, compose_train, tiny_args, anneal):
    # Two iterations of 512 decisions with a 1024-decision budget: the second one runs at half the rate.
    config = compose_train(*tiny_args({"ppo.total_frames": 1024, "ppo.anneal_lr": str(anneal).lower(),
                                       "ppo.learning_rate": 3e-4, "eval.episodes": 4}))
    trainer = Trainer(config, tmp_path / "run")
    trainer.train()
    assert trainer.counters.iteration == 2
    assert trainer.optimizer.param_groups[0]["lr"] == pytest.approx(1.5e-4 if anneal else 3e-4)
