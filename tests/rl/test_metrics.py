"""Per-iteration training statistics (agrl.rl.metrics)."""

from __future__ import annotations

import pytest
import torch
from tensordict import TensorDict

from agrl.core.termination import Outcome
from agrl.rl.metrics import episode_statistics


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

    stats = episode_statistics(data)
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
    idle = episode_statistics(data)
    assert idle["train/episodes"] == 0 and "train/success_rate" not in idle
    assert idle["train/reward_switch_cost"] == pytest.approx(-0.9 / 6)  # logged even when no episode ended
