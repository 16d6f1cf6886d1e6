"""The paper's reward (equations 5-11), as pure batched functions.

R_t = T(S_{t+1}) + F_t with the potential-based shaping
F_t = gamma * Phi(S_{t+1}) - Phi(S_t) (equation 7) and Phi = C + P (equation 8).

Realisation of Phi(S, A): the paper's Phi depends on the state and the action
taken in it, so F_t would need the *next* action A_{t+1}, which does not exist
when the transition is stored. This project evaluates the continuous-action term
C on the change between the two most recent actions, which the state carries
(``last_action`` = A_{t-1} and ``action_before_last`` = A_{t-2}). Then
Phi(S_{t+1}) depends only on S_{t+1} = (..., A_t, A_{t-1}): switching maneuver at
step t costs gamma * (c4 - c5) relative to holding it, and the shaping terms
telescope exactly: sum_t gamma^t F_t = gamma^T Phi(S_T) - Phi(S_0), with
Phi(terminal) = 0, so the optimal policy is unchanged (equations 15-18).

Beyond the paper: :func:`switch_cost_reward` is a plain (non-potential) cost per
change of maneuver. It does change the optimal policy, which is its purpose; it is
off (``switch_cost = 0``) in the paper's four variants.

One function assembles the step reward: :func:`step_reward` (equation 5 plus the switch cost), from the
terms below, each its own function. The batched env (:class:`agrl.envs.guidance.GuidanceEnv`) and the
tests call it; the only second copy is the one-row Python-float form in :mod:`agrl.rows`
(:func:`agrl.rows.potential_row`, :func:`agrl.rows.step_reward_row`), which runs the single gymnasium env
and is tested equal to :func:`step_reward` (``tests/envs/test_rows.py``); its docstring says why it exists.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from agrl.core.aircraft import wrap_angle
from agrl.core.termination import Outcome


@dataclass(frozen=True)
class RewardParameters:
    """Table 2's constants and the two shaping switches; the values are in ``conf/reward/*.yaml``."""

    success: float  # c1
    out_of_airspace: float  # c2
    budget_exhausted: float  # c3
    action_change: float  # c4
    action_hold: float  # c5
    distance_weight: float  # c6, per metre
    heading_weight: float  # c7
    altitude_weight: float  # c8, per metre
    gamma: float
    use_continuous_action: bool  # the C term of equation 8
    use_position: bool  # the P term of equation 8
    switch_cost: float  # NOT in the paper: reward units per instruction, see switch_cost_reward


def termination_reward(outcome: torch.Tensor, params: RewardParameters) -> torch.Tensor:
    """Equation 6: c1 on success, c2 out of the airspace, c3 when the budget is spent, else 0."""
    reward = torch.zeros(outcome.shape, dtype=torch.float32, device=outcome.device)
    reward = torch.where(outcome == Outcome.SUCCESS, params.success, reward)
    reward = torch.where(outcome == Outcome.OUT_OF_AIRSPACE, params.out_of_airspace, reward)
    return torch.where(outcome == Outcome.BUDGET_EXHAUSTED, params.budget_exhausted, reward)


def continuous_action_potential(
    last_action: torch.Tensor, action_before_last: torch.Tensor, params: RewardParameters
) -> torch.Tensor:
    """Equation 9: c4 if the action changed, else c5 (on the last two actions, see module doc)."""
    changed = last_action != action_before_last
    return torch.where(changed, params.action_change, params.action_hold).to(torch.float32)


def position_potential(
    aircraft_state: torch.Tensor, destination_state: torch.Tensor, params: RewardParameters
) -> torch.Tensor:
    """Equations 10-11: P = c6 D + c7 H + c8 A.

    D is minus the horizontal Euclidean distance (equation 11 prints a minus
    inside the square root, a typo), H the cosine of the heading difference and
    A minus the altitude difference.
    """
    dx = aircraft_state[..., 0] - destination_state[..., 0]
    dy = aircraft_state[..., 1] - destination_state[..., 1]
    distance_term = -torch.sqrt(dx * dx + dy * dy)
    heading_term = torch.cos(wrap_angle(aircraft_state[..., 5] - destination_state[..., 3]))
    altitude_term = -(aircraft_state[..., 2] - destination_state[..., 2]).abs()
    return (
        params.distance_weight * distance_term
        + params.heading_weight * heading_term
        + params.altitude_weight * altitude_term
    )


def potential_terms(
    aircraft_state: torch.Tensor,
    destination_state: torch.Tensor,
    last_action: torch.Tensor,
    action_before_last: torch.Tensor,
    terminal: torch.Tensor,
    params: RewardParameters,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Equation 8's two terms (C, P), each 0 when switched off and in terminal states (Phi(terminal) = 0)."""
    zeros = torch.zeros(aircraft_state.shape[:-1], dtype=torch.float32, device=aircraft_state.device)
    action_term = position_term = zeros
    if params.use_continuous_action:
        action_term = zeros + continuous_action_potential(last_action, action_before_last, params)
    if params.use_position:
        position_term = zeros + position_potential(aircraft_state, destination_state, params)
    return (torch.where(terminal, torch.zeros_like(action_term), action_term),
            torch.where(terminal, torch.zeros_like(position_term), position_term))


def potential(
    aircraft_state: torch.Tensor,
    destination_state: torch.Tensor,
    last_action: torch.Tensor,
    action_before_last: torch.Tensor,
    terminal: torch.Tensor,
    params: RewardParameters,
) -> torch.Tensor:
    """Equation 8: Phi = C + P, each term switchable; 0 in terminal states (the sum of :func:`potential_terms`)."""
    action_term, position_term = potential_terms(
        aircraft_state, destination_state, last_action, action_before_last, terminal, params
    )
    return action_term + position_term


def shaping_reward(
    potential_before: torch.Tensor, potential_after: torch.Tensor, params: RewardParameters
) -> torch.Tensor:
    """Equation 7: F = gamma * Phi(S_{t+1}) - Phi(S_t)."""
    return params.gamma * potential_after - potential_before


def switch_cost_reward(instruction: torch.Tensor, params: RewardParameters) -> torch.Tensor:
    """NOT from the paper: -switch_cost on every decision that is an instruction (``instruction``, bool).

    What an instruction is belongs to the action set, and the environment says it
    (:class:`agrl.envs.GuidanceEnv`): for the paper's maneuvers a decision whose maneuver differs from the one
    being flown (an episode starts in steady flight, so the first decision pays only if it commands a maneuver),
    for held targets an action that changes a target. It prices exactly what the evaluation counts as an
    instruction. Unlike equation 9's potential it does not
    telescope, so it changes which policy is optimal: the paper's potential form
    provably cannot make the agent switch less (module doc), this term can.
    The cost is paid when the switch happens (discounted by gamma^t like every
    reward), while the success reward c1 arrives gamma^T later; so with c1 = 20 and
    gamma = 0.99, each extra decision of flight costs about c1 * gamma^T * (1 - gamma)
    (about 0.14 at T = 35), and a switch cost k trades one instruction against about
    k / 0.14 extra decisions.
    """
    return torch.where(instruction, -params.switch_cost, 0.0).to(torch.float32)


#: Names of :func:`step_reward`'s parts, in the order they are summed; the env returns each at every step and
#: training logs their means as ``train/<name>`` (:func:`agrl.rl.metrics.episode_statistics`).
REWARD_PART_KEYS = ("reward_termination", "reward_action_shaping", "reward_position_shaping", "reward_switch_cost")


def step_reward(
    outcome: torch.Tensor,
    aircraft_state: torch.Tensor,
    destination_state: torch.Tensor,
    last_action: torch.Tensor,
    action_before_last: torch.Tensor,
    action: torch.Tensor,
    next_aircraft_state: torch.Tensor,
    next_destination_state: torch.Tensor,
    params: RewardParameters,
    instruction: torch.Tensor,
) -> tuple[torch.Tensor, dict[str, torch.Tensor]]:
    """Equation 5, R = T + F, plus the switch cost: the reward of the decision ``action`` taken in S_t.

    S_t is (``aircraft_state``, ``destination_state``, ``last_action``, ``action_before_last``); S_{t+1} is
    (``next_aircraft_state``, ``next_destination_state``, ``action``, ``last_action``) (equation 4's state
    carries the last two actions, see the module doc), terminal unless ``outcome`` (of S_{t+1}) is
    ``Outcome.RUNNING``. Any batch shape; every argument has it (states with one more, last dimension).

    Returns the total and its parts (:data:`REWARD_PART_KEYS`), which sum to it in that order: the termination
    reward T (:func:`termination_reward`), F split by potential term, gamma C' - C and gamma P' - P (each
    :func:`shaping_reward` of its own :func:`potential_terms` term; exact since equation 7 is linear in
    Phi = C + P), and :func:`switch_cost_reward` on ``instruction`` (which decisions are instructions; see there).
    """
    terminal = outcome != Outcome.RUNNING
    action_before, position_before = potential_terms(
        aircraft_state, destination_state, last_action, action_before_last, torch.zeros_like(terminal), params
    )
    action_after, position_after = potential_terms(
        next_aircraft_state, next_destination_state, action, last_action, terminal, params
    )
    termination, action_shaping, position_shaping, switch_cost = parts = (
        termination_reward(outcome, params),
        shaping_reward(action_before, action_after, params),
        shaping_reward(position_before, position_after, params),
        switch_cost_reward(instruction, params),
    )
    total = termination + action_shaping + position_shaping + switch_cost
    return total, dict(zip(REWARD_PART_KEYS, parts, strict=True))
