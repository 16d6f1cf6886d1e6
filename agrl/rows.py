"""One-row (Python float) forms of the policy observation and the reward: a deliberate second copy of the model.

Why a second copy: on one row, each operation of :mod:`agrl.core`'s batched torch functions costs microseconds
of dispatch, so the torch path at batch 1 costs more than the work it does. The unbatched gymnasium environment
(:mod:`agrl.envs.gym`) and the deployable guide's single query (:meth:`agrl.guide.Guide.instruct`) therefore run
one row in plain Python floats, with this module and its sibling :mod:`agrl.reference` (the one-row physics,
the engine of the single env's decision). These two modules are the only second copies of the model; everything
else calls :mod:`agrl.core`. The figure, per decision of the single env (timeit, best of 5, one torch thread)::

                                   one row, Python floats    agrl.core, batched torch at batch 1
    observation + reward           3.2 us  (this module)     0.52 ms  (policy_observation + step_reward)   ~165x
      of which the reward          1.2 us                    0.37 ms  (step_reward)                        ~300x
    the decision (150 steps)       0.13 ms (agrl.reference)  46 ms    (DecisionSimulator, eager)           ~350x

measured once on 2026-12-04 on the 2-core development machine while it was shared (load average about 5, so
the absolute times are pessimistic; the ratios are what matter), one process at a time, as
``python -m timeit -s "$SETUP" "$STATEMENT"`` with SETUP::

    import torch; torch.set_num_threads(1)
    from agrl.config import guidance_parameters
    from agrl.core.observation import policy_observation
    from agrl.core.reward import step_reward
    from agrl.core.simulation import DecisionSimulator
    from agrl.reference import reference_decision
    from agrl.rows import observation_row, potential_row, step_reward_row
    p = guidance_parameters(); s, r = p.simulation, p.reward
    a, d = (-5000.0, 0.0, 2500.0, 200.0, 0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 0.0)
    A, D, L, N, O = torch.tensor([a]), torch.tensor([d]), torch.tensor([0]), torch.tensor([3]), torch.tensor([0])
    Z = torch.zeros(1); sim = DecisionSimulator(s, p.maneuvers.controls("cpu"))

and the STATEMENTs ``observation_row(a, d, 3, s.airspace, s.limits); step_reward_row(0, potential_row(a, d, 0,
0, False, r), potential_row(a, d, 3, 0, False, r), r, True)`` against ``policy_observation(A, D, N, s.airspace,
s.limits); step_reward(O, A, D, L, L, N, A, D, r, N != L)``, and ``reference_decision(a, d, 0.0, 0.0, 1, s,
p.maneuvers)`` against ``sim(A, D, Z, Z, torch.tensor([1]))``.

What each function copies:

- :func:`observation_row` is :func:`agrl.core.observation.policy_observation`, term by term;
- :func:`potential_row` is :func:`agrl.core.reward.potential` (equations 8-11), and :func:`step_reward_row` on
  two of its values is the total of :func:`agrl.core.reward.step_reward` (equation 5 plus the switch cost), the
  one batched assembly of the reward (the single env keeps Phi(S_{t+1}) as the next step's Phi(S_t), so it
  evaluates one potential per step);
- :func:`initial_aircraft_row` is :func:`agrl.core.initial_states.sample_initial_aircraft` for one row: the
  same draws from the same generator in the same order, in float32 arithmetic, so the same starts to the bit
  (a one-row torch reset cost more than a whole 3 s decision here).

``tests/envs/test_rows.py`` checks each against its torch original on random states (the observation to 1e-12
in float64, the potential and the reward to 1e-7 and 1e-6: c4 and c5 are float32 in :mod:`agrl.core`), so a
change in :mod:`agrl.core` that is not made here fails a test.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import torch

from agrl.core.aircraft import MANEUVER_NAMES, AircraftLimits
from agrl.core.initial_states import InitialStateDistribution
from agrl.core.observation import NEAR_ALTITUDE_SCALE, NEAR_DISTANCE_SCALE
from agrl.core.reward import RewardParameters
from agrl.core.termination import Airspace, Outcome
from agrl.reference import wrap_angle

NUM_MANEUVERS = len(MANEUVER_NAMES)
_RUNNING, _SUCCESS, _OUT_OF_AIRSPACE, _BUDGET_EXHAUSTED = (int(outcome) for outcome in (
    Outcome.RUNNING, Outcome.SUCCESS, Outcome.OUT_OF_AIRSPACE, Outcome.BUDGET_EXHAUSTED))


def observation_row(
    aircraft_state: Sequence[float],
    destination_state: Sequence[float],
    last_action: int,
    airspace: Airspace,
    limits: AircraftLimits,
) -> list[float]:
    """:func:`agrl.core.observation.policy_observation` for one row, as a list of floats (float64)."""
    x, y, z, speed, flight_path_angle, heading, bank = aircraft_state
    dest_x, dest_y, dest_z, dest_heading = destination_state
    half_width = 0.5 * max(airspace.x_max - airspace.x_min, airspace.y_max - airspace.y_min)
    height = airspace.z_max - airspace.z_min

    dx, dy = dest_x - x, dest_y - y
    distance = math.sqrt(dx * dx + dy * dy)
    bearing = wrap_angle(math.atan2(dy, dx) - heading)
    heading_difference = wrap_angle(dest_heading - heading)
    cos_dest, sin_dest = math.cos(dest_heading), math.sin(dest_heading)
    along_track = -(cos_dest * dx + sin_dest * dy)
    cross_track = sin_dest * dx - cos_dest * dy
    features = [
        distance / half_width,
        math.sin(bearing),
        math.cos(bearing),
        (dest_z - z) / height,
        math.tanh((dest_z - z) / NEAR_ALTITUDE_SCALE),
        math.tanh(distance / NEAR_DISTANCE_SCALE),
        math.sin(heading_difference),
        math.cos(heading_difference),
        along_track / half_width,
        cross_track / half_width,
        2.0 * (speed - limits.min_speed) / (limits.max_speed - limits.min_speed) - 1.0,
        flight_path_angle / limits.max_flight_path_angle,
        bank / (0.5 * math.pi),
        2.0 * (z - airspace.z_min) / (airspace.z_max - airspace.z_min) - 1.0,
        2.0 * (x - airspace.x_min) / (airspace.x_max - airspace.x_min) - 1.0,
        2.0 * (y - airspace.y_min) / (airspace.y_max - airspace.y_min) - 1.0,
    ]
    one_hot = [0.0] * NUM_MANEUVERS
    one_hot[last_action] = 1.0
    return features + one_hot


def potential_row(
    aircraft_state: Sequence[float],
    destination_state: Sequence[float],
    last_action: int,
    action_before_last: int,
    terminal: bool,
    params: RewardParameters,
) -> float:
    """:func:`agrl.core.reward.potential` (equations 8-11) for one row."""
    if terminal:
        return 0.0
    value = 0.0
    if params.use_continuous_action:  # equation 9
        value += params.action_change if last_action != action_before_last else params.action_hold
    if params.use_position:  # equations 10-11
        dx = aircraft_state[0] - destination_state[0]
        dy = aircraft_state[1] - destination_state[1]
        value += (
            params.distance_weight * -math.sqrt(dx * dx + dy * dy)
            + params.heading_weight * math.cos(wrap_angle(aircraft_state[5] - destination_state[3]))
            + params.altitude_weight * -abs(aircraft_state[2] - destination_state[2])
        )
    return value


def step_reward_row(outcome: int, potential_before: float, potential_after: float, params: RewardParameters,
                    switched: bool = False) -> float:
    """The total of :func:`agrl.core.reward.step_reward` (equation 5 plus the switch cost) for one row, from the
    two :func:`potential_row` values Phi(S_t), Phi(S_{t+1}) (``switched``: this decision changed the maneuver being
    flown). One sum over Phi = C + P, where the batched function sums C's and P's shaping apart: equal to rounding."""
    # Plain int comparisons: the single gymnasium env calls this at every decision.
    if outcome == _RUNNING:
        termination = 0.0
    elif outcome == _SUCCESS:
        termination = params.success
    elif outcome == _OUT_OF_AIRSPACE:
        termination = params.out_of_airspace
    elif outcome == _BUDGET_EXHAUSTED:
        termination = params.budget_exhausted
    else:
        allowed = ", ".join(f"{code.value} ({code.name})" for code in Outcome)
        raise ValueError(f"outcome={outcome!r} is not allowed: one of {allowed}")
    switch_cost = -params.switch_cost if switched else 0.0
    return termination + params.gamma * potential_after - potential_before + switch_cost


def initial_aircraft_row(distribution: InitialStateDistribution, destination_start: Sequence[float],
                         generator: torch.Generator | None, max_redraws: int = 32) -> tuple[float, ...]:
    """:func:`agrl.core.initial_states.sample_initial_aircraft` for one row (``destination_start``: x, y, ...).

    Each value is one ``torch.rand(1)`` draw mapped as torch maps it in float32 (``low + (high - low) * u``:
    the float scalars rounded to float32, then a float32 product and sum); the redraw test is float32's.
    """
    float32 = np.float32

    def uniform(bounds: tuple[float, float]) -> np.float32:
        low, high = bounds
        return float32(low) + float32(high - low) * float32(torch.rand(1, generator=generator).item())

    dest_x, dest_y = float32(destination_start[0]), float32(destination_start[1])
    min_distance = float32(distribution.min_horizontal_distance)
    x, y = uniform(distribution.x_range), uniform(distribution.y_range)
    for _ in range(max_redraws):
        if not np.hypot(x - dest_x, y - dest_y) <= min_distance:
            break
        x, y = uniform(distribution.x_range), uniform(distribution.y_range)
    else:
        raise ValueError(
            f"min_horizontal_distance={distribution.min_horizontal_distance} m leaves (almost) no room "
            f"in the start box x={distribution.x_range}, y={distribution.y_range}"
        )
    z, speed = uniform(distribution.z_range), uniform(distribution.speed_range)
    return float(x), float(y), float(z), float(speed), 0.0, 0.0, 0.0
