"""The actor networks' helpers: the logits accessor, the ensemble of several actors and the collection-time sampler
(agrl.rl.models)."""

from __future__ import annotations

import pytest
import torch
from tensordict import TensorDict
from torchrl.envs import ExplorationType, set_exploration_type

from agrl.core.observation import observation_size
from agrl.rl.models import CategoricalSampler, logits_network, make_actor, make_critic, make_ensemble_actor


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


@pytest.mark.parametrize("batch", [(256,), (32, 8)])
@pytest.mark.parametrize("num_actions", [7, 19])
def test_the_sampler_draws_the_actors_actions_bit_for_bit(batch, num_actions):
    """A collector's policy step: the same actions and log-probabilities as the ProbabilisticActor, from the same
    draws of the default generator, so a run collected with either is the same run."""
    torch.manual_seed(3)
    actor = make_actor([16, 16], "tanh", num_actions=num_actions)
    with torch.no_grad():
        logits_network(actor)[-1].weight.mul_(30.0)  # varied probabilities, not near-uniform ones
    observations = _observations(256).reshape(*batch)
    with torch.no_grad(), set_exploration_type(ExplorationType.RANDOM):
        torch.manual_seed(11)
        expected = actor(observations.clone())
        torch.manual_seed(11)
        sampled = CategoricalSampler(actor)(observations.clone())
        after = torch.rand(1)  # both consumed the generator alike
        torch.manual_seed(11)
        actor(observations.clone())
        assert torch.equal(after, torch.rand(1))
    assert set(sampled.keys()) == {"observation", "action", "action_log_prob"}
    assert sampled["action"].dtype == expected["action"].dtype and sampled["action"].shape == batch
    assert torch.equal(sampled["action"], expected["action"])
    assert torch.equal(sampled["action_log_prob"], expected["action_log_prob"])
    assert len(set(sampled["action"].flatten().tolist())) > 1


@pytest.mark.parametrize("exploration", [ExplorationType.DETERMINISTIC, ExplorationType.MODE, None])
def test_the_sampler_takes_the_actors_deterministic_action_outside_random_exploration(exploration):
    """Also with no exploration type set, as when a collector first runs its policy to learn its outputs."""
    actor, observations = _actor(0), _observations()
    with torch.no_grad(), set_exploration_type(ExplorationType.DETERMINISTIC):
        expected = actor(observations.clone())
    with torch.no_grad(), set_exploration_type(exploration):
        chosen = CategoricalSampler(actor)(observations.clone())
    assert set(chosen.keys()) == {"observation", "action", "action_log_prob"}
    assert torch.equal(chosen["action"], expected["action"])
    assert torch.equal(chosen["action_log_prob"], expected["action_log_prob"])


def test_the_sampler_shares_the_actors_parameters_once():
    actor = _actor(0)
    sampler = CategoricalSampler(actor)
    assert [id(parameter) for parameter in sampler.parameters()] == [id(parameter) for parameter in actor.parameters()]
    assert sampler.state_dict().keys() == {f"actor.{name}" for name in actor.state_dict()}


def test_the_sampler_refuses_what_is_not_an_actor_of_make_actor():
    with pytest.raises(ValueError, match="make_actor"):
        CategoricalSampler(make_critic([16], "tanh"))


@pytest.mark.parametrize("inplace", [True, False, "empty"])
def test_actor_and_critic_write_what_tensordicts_modules_write(inplace):
    """The actor's logits step and the critic write their outputs directly (agrl.rl.models._TensorOutputs): the same
    TensorDict as tensordict's own modules, in place or not."""
    from tensordict.nn import TensorDictModule
    from torchrl.modules import ValueOperator

    from agrl.rl.models import Critic, LogitsModule

    torch.manual_seed(0)
    network, value_network = make_actor([16], "tanh").module[0].module, make_critic([16], "tanh").module
    pairs = [(LogitsModule(network, in_keys=["observation"], out_keys=["logits"], inplace=inplace),
              TensorDictModule(network, in_keys=["observation"], out_keys=["logits"], inplace=inplace))]
    if inplace is True:  # a ValueOperator always writes in place
        pairs.append((Critic(value_network, in_keys=["observation"]),
                      ValueOperator(value_network, in_keys=["observation"])))
    for ours, theirs in pairs:
        written, expected = ours(_observations(8)), theirs(_observations(8))
        assert set(written.keys(True)) == set(expected.keys(True)) and written.batch_size == expected.batch_size
        for key in expected.keys(True, True):
            assert torch.equal(written[key], expected[key]), key


def test_actor_and_critic_outputs_skip_tensordicts_conversion(monkeypatch):
    """Their output tensors are not passed through ``TensorDict.from_any`` (which searches ``sys.path`` for pandas
    before returning a tensor as it is)."""
    def refuse(cls, obj, **kwargs):
        raise AssertionError(f"TensorDict.from_any called on {type(obj).__name__}")

    actor, critic = make_actor([16], "tanh"), make_critic([16], "tanh")
    monkeypatch.setattr(TensorDict, "from_any", classmethod(refuse))
    observations = _observations(8)
    actor(observations)
    critic(observations)
    assert {"logits", "action", "action_log_prob", "state_value"} <= set(observations.keys())
