"""The actor networks' helpers: the logits accessor and the ensemble of several actors (agrl.rl.models)."""

from __future__ import annotations

import pytest
import torch
from tensordict import TensorDict
from torchrl.envs import ExplorationType, set_exploration_type

from agrl.core.observation import observation_size
from agrl.rl.models import logits_network, make_actor, make_critic, make_ensemble_actor


def _actor(seed: int):
    torch.manual_seed(seed)
    actor = make_actor([16, 16], "tanh")
    with torch.no_grad():
        logits_network(actor)[-1].weight.mul_(100.0)  # undo make_actor's near-uniform output layer
    return actor


def _observations(count: int = 256) -> TensorDict:
    generator = torch.Generator().manual_seed(7)
    return TensorDict({"observation": torch.randn(count, observation_size("relative"), generator=generator)},
                      batch_size=[count])


def test_an_ensemble_of_one_is_that_actor():
    actor, observations = _actor(0), _observations()
    ensemble = make_ensemble_actor([actor])
    with set_exploration_type(ExplorationType.DETERMINISTIC):
        alone, mixed = actor(observations.clone()), ensemble(observations.clone())
    assert torch.equal(alone["action"], mixed["action"])
    torch.testing.assert_close(mixed["action_log_prob"], alone["action_log_prob"])


def test_the_ensemble_flies_the_mean_of_its_members_probabilities():
    members, observations = [_actor(seed) for seed in range(3)], _observations()
    probabilities = torch.stack([logits_network(member)(observations["observation"]).softmax(-1)
                                 for member in members]).mean(0)
    ensemble = make_ensemble_actor(members)
    with set_exploration_type(ExplorationType.DETERMINISTIC):
        chosen = ensemble(observations.clone())
    torch.testing.assert_close(logits_network(ensemble)(observations["observation"]).exp(), probabilities)
    assert torch.equal(chosen["action"], probabilities.argmax(-1))
    torch.testing.assert_close(chosen["action_log_prob"], probabilities.gather(-1, chosen["action"][:, None])
                               .squeeze(-1).log())
    # The members disagree on some states, so the ensemble is not simply one of them.
    member_actions = torch.stack([logits_network(member)(observations["observation"]).argmax(-1) for member in members])
    assert bool((member_actions != member_actions[0]).any())


def test_an_ensemble_refuses_what_is_not_an_actor_of_make_actor():
    with pytest.raises(ValueError, match="make_actor"):
        make_ensemble_actor([_actor(0), make_critic([16], "tanh")])
