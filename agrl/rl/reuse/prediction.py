"""Destination position prediction (the paper's equations 19-20) and the baseline B's answers to it.

:func:`destination_prediction` gives each episode's destination state at every decision 0..budget: the recorded
trajectory inside the episode, the motion model past its end (equation 19). :class:`BaselinePolicy` is the frozen
baseline B as the search queries it: its input with the destination fields replaced by a predicted destination
state (equation 20), and its deterministic action with that action's log-probability.

States are the environment's: the aircraft ``(..., 7)`` and the destination ``(x, y, z, heading)`` ``(..., 4)``
in m and rad; speeds in m/s, turn rates in rad/s.
"""

from __future__ import annotations

import torch
from tensordict import TensorDict, TensorDictBase
from torchrl.envs import ExplorationType, set_exploration_type

from agrl.core.destinations import DestinationState, move_destination
from agrl.core.observation import in_destination_frame, observation_function, target_observation_function
from agrl.core.parameters import GuidanceParameters
from agrl.core.simulation import SimulationParameters
from agrl.rl.models import logits_network


def destination_prediction(
    rows: TensorDictBase, starts: torch.Tensor, episode_ids: torch.Tensor, params: GuidanceParameters,
) -> tuple[torch.Tensor, torch.Tensor]:
    """The destination's state at every decision 0..budget of each episode starting at a row of ``starts``.

    ``rows``: flat rows ``(N,)`` in which each episode's rows are contiguous (the collector's env-major layout),
    with ``destination_state`` and ``("next", ...)`` ``destination_state``, ``destination_speed``,
    ``destination_turn_rate`` and ``done``; ``starts`` ``(E,)``: the episodes' first rows; ``episode_ids`` ``(N,)``:
    each row's episode. Returns ``trajectory (E, budget + 1, 4)`` (index n: the state at decision n, index 0 the
    start) and ``motion (E, budget, 2)`` (the destination's speed m/s and turn rate rad/s during each decision).

    Inside the episode both are the recorded ones; past its last recorded transition (its end, or the batch's)
    the last recorded speed and turn rate are kept, one exact arc of the motion model per decision, bouncing off
    the airspace's walls as the environment's destination does.
    """
    budget = params.max_decisions
    count = rows.numel()
    steps = torch.arange(budget, device=rows.device)
    index = (starts[:, None] + steps[None, :]).clamp(max=count - 1)
    recorded = (episode_ids[index] == episode_ids[starts][:, None]) & (starts[:, None] + steps[None, :] < count)
    length = recorded.sum(-1)  # transitions of each episode inside the batch
    next_rows = rows["next"]
    motion = torch.stack((next_rows["destination_speed"][index], next_rows["destination_turn_rate"][index]), -1)
    last_motion = motion.gather(1, (length - 1).clamp(min=0)[:, None, None].expand(-1, 1, 2))
    motion = torch.where(recorded[..., None], motion, last_motion)

    # A row that ends inside a decision is frozen at the ending sub-step, so the destination recorded
    # after an episode's last transition is not where it is one decision later: predict that one too.
    recorded_after = recorded & ~next_rows["done"][index].squeeze(-1)

    states = [rows["destination_state"][starts]]
    after = next_rows["destination_state"][index]
    airspace = params.simulation.airspace
    period = params.simulation.decision_period
    for step in range(budget):
        # Recorded positions where known; beyond the episode's end, the motion model (one exact arc per decision).
        predicted = move_destination(
            DestinationState.from_tensor(states[-1]), motion[:, step, 0], motion[:, step, 1], period,
            (airspace.x_min, airspace.x_max), (airspace.y_min, airspace.y_max),
        ).to_tensor()
        states.append(torch.where(recorded_after[:, step, None], after[:, step], predicted))
    return torch.stack(states, 1), motion


class BaselinePolicy:
    """The frozen baseline B, queried on predicted destinations in deterministic mode (argmax), without gradients.

    ``actor``: B's TorchRL actor (``observation -> action``); ``simulation``: the environment's simulation
    parameters (airspace and limits normalise the observation); ``observation``: B's own input, ``relative`` or
    ``absolute`` (its checkpoint's ``agent.observation``, which may differ from the trained agent's);
    ``holds_targets``: B flies held targets (``actions=targets``), so what it reads beside the state is the targets
    it holds ``(..., 3)`` instead of the maneuver flown.

    ``logits`` is B's ``observation -> logits`` network when the actor is built like
    :func:`agrl.rl.models.make_actor` (then it is called directly, without TensorDict and distribution wrappers,
    with the actor's results bit for bit), or None: with ``direct=False``, or for any other actor, the actor is
    queried whole.
    """

    def __init__(self, actor: torch.nn.Module, simulation: SimulationParameters, observation: str = "relative", *,
                 direct: bool = True, holds_targets: bool = False):
        self.actor = actor
        self.simulation = simulation
        self.observation_kind = observation
        self.holds_targets = holds_targets
        self.observation_function = (target_observation_function(observation) if holds_targets
                                     else observation_function(observation))
        self.logits = logits_network(actor) if direct else None

    def observation(
        self, aircraft_state: torch.Tensor, predicted_destination: torch.Tensor, last_action: torch.Tensor
    ) -> torch.Tensor:
        """B's input ``(..., features)`` with the destination fields replaced by the prediction (equation 20).

        ``aircraft_state (..., 7)``, ``predicted_destination (..., 4)``, ``last_action (...)`` (for B holding
        targets: the held targets ``(..., 3)``). The relative observation describes the aircraft from the destination
        it is given, so the prediction goes in as it is. With the absolute one (equation 4), B has only seen the
        fixed destination at the origin: the state is moved into the predicted destination's frame first (section
        5.1, :func:`in_destination_frame`), held heading and altitude targets with it.
        """
        simulation = self.simulation
        if self.observation_kind == "absolute":
            if self.holds_targets:
                shift = torch.stack((predicted_destination[..., 3], predicted_destination[..., 2],
                                     torch.zeros_like(predicted_destination[..., 2])), dim=-1)
                last_action = last_action - shift
            aircraft_state, predicted_destination = in_destination_frame(aircraft_state, predicted_destination)
        return self.observation_function(aircraft_state, predicted_destination, last_action, simulation.airspace,
                                         simulation.limits)

    def actions(self, state: TensorDictBase, predicted_destination: torch.Tensor) -> torch.Tensor:
        """B's deterministic action ``(...)`` on ``state`` (``aircraft_state``, ``last_action`` or, for B holding
        targets, ``held_targets``) whose destination fields are ``predicted_destination (..., 4)`` (equation 20)."""
        memory = state["held_targets"] if self.holds_targets else state["last_action"]
        return self.mode(self.observation(state["aircraft_state"], predicted_destination, memory))

    def mode(self, observation: torch.Tensor) -> torch.Tensor:
        """B's action in deterministic mode on ``observation (..., features)``: the mode of its distribution (the
        argmax for a categorical), whatever the caller's exploration setting."""
        return self.mode_and_log_prob(observation)[0]

    @torch.no_grad()
    def mode_and_log_prob(self, observation: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """B's deterministic action ``(...)`` and its log-probability under B ``(...)``, from one forward pass (the
        search keeps both, so that the kept rows' B log-probability needs no second pass of B)."""
        if self.logits is not None:
            # What the actor computes in DETERMINISTIC mode (Categorical(logits).mode), without its TensorDict
            # and distribution wrappers: the search calls this once per time step (tested equal to the actor).
            logits = self.logits(observation)
            # Categorical(logits=logits), op for op: normalised logits; the mode is their softmax's argmax and
            # the log-probability of an action its normalised logit.
            normalised = logits - logits.logsumexp(dim=-1, keepdim=True)
            action = torch.softmax(normalised, dim=-1).argmax(dim=-1)
            return action, normalised.gather(-1, action[..., None]).squeeze(-1)
        query = TensorDict({"observation": observation}, batch_size=observation.shape[:-1], device=observation.device)
        with set_exploration_type(ExplorationType.DETERMINISTIC):
            action = self.actor(query)["action"]
        return action, self.actor.get_dist(query).log_prob(action)
