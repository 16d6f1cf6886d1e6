"""The partial reset's helpers (agrl.envs.partial_reset); GuidanceEnv.maybe_reset itself is tested against TorchRL's
in tests/envs/test_guidance.py."""

from __future__ import annotations

import dataclasses

import pytest
import torch
from tensordict import TensorDict

from agrl.core.termination import Outcome
from agrl.envs import GuidanceEnv
from agrl.envs.partial_reset import ZERO_AT_START, put_rows


@pytest.mark.parametrize("actions", ["maneuvers", "targets"])
def test_a_new_episodes_fields_besides_its_start_fields_are_those_zero_at_start(actions, paper_parameters,
                                                                                compose_parameters):
    """The partial reset writes the start fields and zeroes the others: a reset's rows must agree with that."""
    params = paper_parameters
    if actions == "targets":
        params = dataclasses.replace(params, actions=compose_parameters("actions=targets").actions)
    state = GuidanceEnv(params, num_envs=8, seed=0).reset()
    starts = GuidanceEnv(params, num_envs=8, seed=0).start_fields(
        state["aircraft_state"], state["destination_state"], state["destination_speed"],
        state["destination_turn_rate"])
    assert set(state.keys()) == set(starts.keys()) | set(ZERO_AT_START)
    assert not set(starts.keys()) & set(ZERO_AT_START)
    for key in starts.keys():
        assert torch.equal(starts[key], state[key]), key
    for key, (dtype, *shape) in ZERO_AT_START.items():
        assert state[key].dtype == dtype and state[key].shape == (8, *shape) and not state[key].any(), key
    assert bool((state["outcome"] == Outcome.RUNNING).all())


def test_put_rows_writes_out_of_place_zeroes_what_the_new_rows_lack_and_adds_what_only_they_have():
    old = torch.arange(4.0)
    state = TensorDict({"kept": old, "lacking": torch.ones(4, dtype=torch.int64),
                        "nested": TensorDict({"ids": torch.arange(4)}, [4])}, [4])
    new = TensorDict({"kept": torch.tensor([10.0, 30.0]), "added": torch.tensor([7.0, 8.0])}, [2])
    put_rows(state, new, torch.tensor([1, 3]))
    assert state["kept"].tolist() == [0.0, 10.0, 2.0, 30.0] and old.tolist() == [0.0, 1.0, 2.0, 3.0]
    assert state["lacking"].tolist() == [1, 0, 1, 0] and state["nested", "ids"].tolist() == [0, 0, 2, 0]
    assert state["added"].tolist() == [0.0, 7.0, 0.0, 8.0]
