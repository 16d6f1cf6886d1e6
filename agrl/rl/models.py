"""Actor (a categorical policy over the agent's actions: the 7 maneuvers or the target-holding actions) and critic
networks as TorchRL modules."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import torch
from tensordict import TensorDict, TensorDictBase
from tensordict.nn import InteractionType, TensorDictModule, TensorDictModuleBase
from tensordict.nn.probabilistic import interaction_type
from torch import nn
from torchrl.modules import MLP, ProbabilisticActor, ValueOperator

from agrl.config import saved_agent_config, saved_guidance_parameters
from agrl.core.observation import observation_size
from agrl.envs.guidance import NUM_ACTIONS
from agrl.rl.checkpoint import load_checkpoint, load_module_state, resolve_checkpoint_path

ACTIVATIONS = {"tanh": nn.Tanh, "relu": nn.ReLU, "elu": nn.ELU}


def make_agent(agent, params, device: torch.device | str = "cpu") -> tuple[ProbabilisticActor, ValueOperator]:
    """The actor and critic of ``agent`` (an ``agent`` config section: sizes, activation, observation) for the task
    ``params`` (a :class:`agrl.core.parameters.GuidanceParameters`: its action set sets the output and the
    input's last features)."""
    holds_targets, num_actions = params.actions.holds_targets, params.num_actions
    return (make_actor(agent.actor_hidden, agent.activation, device, agent.observation, num_actions, holds_targets),
            make_critic(agent.critic_hidden, agent.activation, device, agent.observation, holds_targets))


def load_agent(reference: str, device: torch.device | str = "cpu") -> tuple[ProbabilisticActor, dict, Path]:
    """(actor in eval mode, saved config dict, path) of a checkpoint file, run directory or shipped agent's name;
    ``GuidanceEnv.for_saved_agent(saved, ...)`` is the env it acts in."""
    path = resolve_checkpoint_path(reference)
    payload = load_checkpoint(path, required=("actor", "config"))
    actor, _ = make_agent(saved_agent_config(payload["config"]), saved_guidance_parameters(payload["config"]), device)
    load_module_state(actor, payload["actor"], path, "actor")
    return actor.eval(), payload["config"], path


def make_actor(hidden: list[int], activation: str, device: torch.device | str = "cpu",
               observation: str = "relative", num_actions: int = NUM_ACTIONS,
               holds_targets: bool = False) -> ProbabilisticActor:
    """``observation -> logits -> action`` with ``action_log_prob``; deterministic mode is the argmax.
    ``observation`` (relative or absolute, ``agent.observation``) and ``holds_targets`` (an agent of
    ``actions=targets``) set the input width, ``num_actions`` the output's (the 7 maneuvers by default)."""
    network = MLP(
        in_features=observation_size(observation, holds_targets), out_features=num_actions, num_cells=list(hidden),
        activation_class=ACTIVATIONS[activation], device=device,
    )
    # Small final layer: the initial policy is close to uniform over the actions.
    with torch.no_grad():
        network[-1].weight.mul_(0.01)
        network[-1].bias.zero_()
    return _categorical_actor(network)


class _TensorOutputs:
    """Writes a module's output tensors into the TensorDict as they are (anything else as tensordict does).

    tensordict's ``TensorDictModule`` passes each output through ``TensorDict.from_any``, which returns a tensor
    unchanged, but only after asking ``importlib`` whether pandas is installed: a search of ``sys.path`` where it is
    not, twice a PPO minibatch (actor and critic) of the eager loss (``ppo.compile_loss=false``, or where compiling
    fails; a compiled loss skips the question). A duplicate of ``_write_to_tensordict`` for plain tensors, the price
    of an eager update about 7 % shorter at the defaults' shape (``benchmarks.bench_peer``, paired with tensordict's
    path: docs/benchmarks.md, "What each design choice buys").
    """

    def _write_to_tensordict(self, tensordict, tensors, tensordict_out=None, out_keys=None):
        out_keys = self.out_keys_source if out_keys is None else out_keys
        if len(tensors) != len(out_keys) or not all(type(tensor) is torch.Tensor for tensor in tensors):
            return super()._write_to_tensordict(tensordict, tensors, tensordict_out, out_keys)
        if tensordict_out is None:
            if self.inplace is True:
                tensordict_out = tensordict
            else:
                tensordict_out = tensordict.empty() if self.inplace == "empty" else TensorDict()
        for key, tensor in zip(out_keys, tensors, strict=True):
            if key != "_":
                tensordict_out.set(key, tensor)
        return tensordict_out


class LogitsModule(_TensorOutputs, TensorDictModule):
    """A categorical actor's ``observation -> logits`` step: a ``TensorDictModule`` writing its output directly."""


class Critic(_TensorOutputs, ValueOperator):
    """The critic: a ``ValueOperator`` writing its ``state_value`` directly."""


def _categorical_actor(logits: nn.Module) -> ProbabilisticActor:
    """``observation -> logits`` (``logits`` a network), then a ``Categorical``: the form :func:`logits_network`
    recognises."""
    return ProbabilisticActor(
        LogitsModule(logits, in_keys=["observation"], out_keys=["logits"]),
        in_keys=["logits"],
        out_keys=["action"],
        distribution_class=torch.distributions.Categorical,
        return_log_prob=True,
    )


def make_critic(hidden: list[int], activation: str, device: torch.device | str = "cpu",
                observation: str = "relative", holds_targets: bool = False) -> Critic:
    network = MLP(
        in_features=observation_size(observation, holds_targets), out_features=1, num_cells=list(hidden),
        activation_class=ACTIVATIONS[activation], device=device,
    )
    return Critic(network, in_keys=["observation"])


def network_signature(module: nn.Module) -> dict[str, list[int]]:
    """Parameter names and shapes: what a checkpoint must match to be loaded into ``module``."""
    return {name: list(tensor.shape) for name, tensor in module.state_dict().items()}


def logits_network(actor: torch.nn.Module) -> torch.nn.Module | None:
    """The ``observation -> logits`` network of a categorical actor (as :func:`make_actor` builds
    it: a logits module, then a ``Categorical`` on them), or None for any other actor (queried as a whole)."""
    if not isinstance(actor, ProbabilisticActor) or len(actor.module) != 2:
        return None
    logits, distribution = actor.module
    if (isinstance(logits, TensorDictModule) and list(logits.in_keys) == ["observation"]
            and list(logits.out_keys) == ["logits"] and list(distribution.in_keys) == ["logits"]
            and distribution.distribution_class is torch.distributions.Categorical
            and not distribution.distribution_kwargs):
        return logits.module
    return None


class CategoricalSampler(TensorDictModuleBase):
    """A categorical actor's policy step for collection: ``observation -> action, action_log_prob``.

    Under ``ExplorationType.RANDOM`` (a collector's) it draws what ``actor`` would, bit for bit and from the same
    draws of the default generator, computed as ``torch.distributions.Categorical`` does: normalised logits, their
    softmax, one ``torch.multinomial`` draw with replacement, the drawn action's normalised logit. Under any other
    exploration type (or none) it takes the most probable action, as the actor's deterministic mode does. It skips
    what the ``ProbabilisticActor`` adds around that: the ``Distribution`` object, tensordict's module plumbing
    (which asks ``importlib`` whether pandas is installed on every call) and the ``logits`` it writes into every
    stored decision. Its parameters are ``actor``'s.
    """

    def __init__(self, actor: ProbabilisticActor):
        super().__init__()
        network = logits_network(actor)
        if network is None:
            raise ValueError("CategoricalSampler needs a categorical actor built by make_actor")
        self.actor = actor
        self.in_keys = ["observation"]
        self.out_keys = ["action", "action_log_prob"]
        self._logits = (network,)  # a tuple: the network stays registered once, under ``actor``

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        logits = self._logits[0](tensordict.get("observation"))
        logits = logits - logits.logsumexp(-1, keepdim=True)
        probabilities = logits.softmax(-1)
        if interaction_type() is InteractionType.RANDOM:
            action = torch.multinomial(probabilities.reshape(-1, probabilities.shape[-1]), 1, True)
            action = action.reshape(logits.shape[:-1])
        else:
            action = probabilities.argmax(-1)
        tensordict.set("action", action)
        tensordict.set("action_log_prob", logits.gather(-1, action.unsqueeze(-1)).squeeze(-1))
        return tensordict


class MeanProbabilityLogits(nn.Module):
    """Several ``observation -> logits`` networks as one: the log of the mean of their action probabilities.

    A ``Categorical`` on these logits is the ensemble's mixture policy; its mode is the action the members
    give the most probability on average.
    """

    def __init__(self, networks: Sequence[nn.Module]):
        super().__init__()
        if not networks:
            raise ValueError("an ensemble needs at least one network")
        self.networks = nn.ModuleList(networks)

    def forward(self, observation: torch.Tensor) -> torch.Tensor:
        log_probabilities = torch.stack([network(observation).log_softmax(-1) for network in self.networks])
        return torch.logsumexp(log_probabilities, 0) - math.log(len(self.networks))


def make_ensemble_actor(actors: Sequence[ProbabilisticActor]) -> ProbabilisticActor:
    """One actor flying the mixture of ``actors``' policies (each built like :func:`make_actor`, same input)."""
    networks = [logits_network(actor) for actor in actors]
    if any(network is None for network in networks):
        raise ValueError("every member of an ensemble must be an actor built by make_actor")
    return _categorical_actor(MeanProbabilityLogits(networks))
