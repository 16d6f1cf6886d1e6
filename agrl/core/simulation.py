"""One decision step: 150 integration steps of 20 ms with success checked at each.

The decision period (3 s) and the integration step (20 ms) come from the paper's
Tables 1 and 2. Success (equation 2) and leaving the airspace (equation 1) are
checked after every integration step, so an aircraft that passes through the
tolerance region between two decisions is caught. A finished row is frozen.

:class:`DecisionSimulator` optionally fuses the per-substep arithmetic with
``torch.compile``; the eager and fused paths compute the same function. The fused
path runs ``substeps_per_call`` integration steps per compiled call (one kernel):
on a CPU the per-call overhead (about 50 us) otherwise dominates small batches.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import torch

from agrl.core.aircraft import (
    GRAVITY,
    AircraftLimits,
    AircraftState,
    ManeuverControls,
    ManeuverLoads,
    integrate_loads,
    load_factors_and_bank,
    wrap_angle,
)
from agrl.core.autopilot import AutopilotParameters, HeldTargets, autopilot_loads
from agrl.core.compiled import CachedRowwiseCompile, EagerFallback
from agrl.core.destinations import DestinationState, move_destination
from agrl.core.termination import Airspace, Outcome, SuccessTolerance, is_outside_airspace, is_success


@dataclass(frozen=True)
class SimulationParameters:
    """The simulation's steps, box, tolerances and limits; the values are in ``conf/simulation/paper.yaml``."""

    integration_step: float  # s (Table 1: 20 ms)
    decision_period: float  # s (Table 2's "training time-step": 3 s)
    airspace: Airspace
    tolerance: SuccessTolerance
    limits: AircraftLimits
    gravity: float = GRAVITY  # m/s^2: a physical constant, the one value conf/ does not hold

    @property
    def substeps(self) -> int:
        steps = round(self.decision_period / self.integration_step)
        if steps < 1 or abs(steps * self.integration_step - self.decision_period) > 1e-9:
            raise ValueError(
                f"decision_period={self.decision_period} s must be a whole multiple of "
                f"integration_step={self.integration_step} s"
            )
        return steps


class DecisionResult(NamedTuple):
    aircraft_state: torch.Tensor  # (..., 7), heading wrapped
    destination_state: torch.Tensor  # (..., 4), heading wrapped
    outcome: torch.Tensor  # int64 Outcome code: RUNNING, SUCCESS or OUT_OF_AIRSPACE


#: How inductor compiles the fused step (the simulator's throughput with and without them: docs/results/history.md,
#: "Benchmarks", commit 4a77b09):
#: - ``cpp.min_chunk_size``: a CPU kernel gets several threads only from this many rows per thread (default
#:   512). Inductor counts elements, not work, and one row here is ``substeps_per_call`` integration steps of
#:   trigonometry; with the default, the collector's 512 rows ran on one thread, and so did the graph for changing
#:   sizes whenever it was first compiled at fewer than 1 024 rows. Ignored on GPUs and with one thread.
#: - ``max_fusion_size``: at most this many operations per fused kernel (default 64) cut the ten steps into
#:   three loops over the rows, passing the state between them through memory. One loop keeps the state in
#:   registers for the whole decision, which more than halves its time, and the cold compilation is no longer.
_INDUCTOR_OPTIONS = {"cpp.min_chunk_size": 1, "max_fusion_size": 100_000}


def _substep(
    aircraft: AircraftState,
    destination: DestinationState,
    active: torch.Tensor,
    outcome: torch.Tensor,
    destination_speed: torch.Tensor,
    destination_turn_rate: torch.Tensor,
    axial_excess: torch.Tensor,
    normal_load: torch.Tensor,
    turn_direction: torch.Tensor,
    params: SimulationParameters,
):
    """One integration step under one maneuver's control law."""
    loads = load_factors_and_bank(aircraft.flight_path_angle, axial_excess, normal_load, turn_direction)
    return _advance(aircraft, loads, destination, destination_speed, destination_turn_rate, active, outcome, params)


def _advance(
    aircraft: AircraftState,
    loads: ManeuverLoads,
    destination: DestinationState,
    destination_speed: torch.Tensor,
    destination_turn_rate: torch.Tensor,
    active: torch.Tensor,
    outcome: torch.Tensor,
    params: SimulationParameters,
):
    """One integration step of aircraft and destination at the given loads, then the success and airspace checks."""
    airspace = params.airspace
    # A finished row is frozen by a zero step (x + rate * 0 = x exactly): the next step's trigonometric
    # functions then read the very values this step wrote, which lets the fused kernel compute them once.
    dt = params.integration_step * active.to(aircraft.speed.dtype)
    moved = integrate_loads(aircraft, loads, dt, params.limits, params.gravity)
    destination = move_destination(
        destination,
        destination_speed,
        destination_turn_rate,
        dt,
        (airspace.x_min, airspace.x_max),
        (airspace.y_min, airspace.y_max),
    )
    aircraft = moved._replace(bank=torch.where(active, moved.bank, aircraft.bank))  # the control law sets the bank
    succeeded = active & is_success(
        aircraft.x, aircraft.y, aircraft.z, aircraft.heading, *destination, params.tolerance
    )
    left = active & ~succeeded & is_outside_airspace(aircraft.x, aircraft.y, aircraft.z, airspace)
    outcome = torch.where(succeeded, Outcome.SUCCESS, torch.where(left, Outcome.OUT_OF_AIRSPACE, outcome))
    return aircraft, destination, active & ~succeeded & ~left, outcome


def _substeps(*args):
    """``count`` integration steps in a row (``args`` = :func:`_substep`'s, then ``count``); fused when compiled.
    The results are the new values of the first four arguments (a decision repeats the call on them)."""
    *state, params, count = args
    aircraft, destination, active, outcome, speed, turn_rate, axial_excess, normal_load, turn_direction = state
    for _ in range(count):
        aircraft, destination, active, outcome = _substep(
            aircraft, destination, active, outcome, speed, turn_rate, axial_excess, normal_load, turn_direction,
            params,
        )
    return aircraft, destination, active, outcome


def _target_substeps(*args):
    """``count`` integration steps with the autopilot flying held targets (``args``: aircraft, destination, active,
    outcome, the destination's speed and turn rate, the target heading, altitude and speed, then the simulation's
    and the autopilot's parameters and ``count``); fused when compiled. The results are the new values of the first
    four arguments."""
    *state, params, autopilot, count = args
    aircraft, destination, active, outcome, speed, turn_rate, heading, altitude, target_speed = state
    targets = HeldTargets(heading, altitude, target_speed)
    for _ in range(count):
        loads = autopilot_loads(aircraft, targets, params.limits, autopilot, params.gravity)
        aircraft, destination, active, outcome = _advance(
            aircraft, loads, destination, speed, turn_rate, active, outcome, params
        )
    return aircraft, destination, active, outcome


class DecisionSimulator:
    """Runs decision steps for a batch of aircraft and destinations.

    ``compile=True`` fuses ``substeps_per_call`` integration steps into one kernel with
    ``torch.compile`` (it must divide the 150 steps of a decision); if that is unavailable
    (no compiler, unsupported platform) it warns once and runs eagerly, one step at a time.
    One compilation serves every batch size; it takes 20-30 s the first time and is kept
    in the user's compile cache (:func:`agrl.core.compiled.compile_cache_dir`), from which a
    later process loads it in under a second.
    """

    def __init__(
        self, params: SimulationParameters, controls: ManeuverControls, compile: bool = False,
        substeps_per_call: int = 10, autopilot: AutopilotParameters | None = None,
    ):
        self.params = params
        self.controls = controls
        self.autopilot = autopilot
        self._compile = compile
        self._targets_run: EagerFallback | None = None
        self.substeps = params.substeps
        if substeps_per_call < 1 or self.substeps % substeps_per_call:
            raise ValueError(
                f"substeps_per_call={substeps_per_call} is not allowed: a divisor of the {self.substeps} "
                "integration steps of a decision"
            )
        self.substeps_per_call = substeps_per_call if compile else 1
        compiled = _substeps
        if compile:  # one compilation for every batch size, kept on disk for the next process (agrl.core.compiled)
            compiled = CachedRowwiseCompile(_substeps, "simulation step",
                                            key=f"{params!r} x{self.substeps_per_call}", options=_INDUCTOR_OPTIONS)
        self._substeps = EagerFallback(compiled, _substeps, "the simulation step")

    @property
    def compiled(self) -> bool:
        return self._substeps.compiled

    def __call__(
        self,
        aircraft_state: torch.Tensor,
        destination_state: torch.Tensor,
        destination_speed: torch.Tensor,
        destination_turn_rate: torch.Tensor,
        action: torch.Tensor,
        active: torch.Tensor | None = None,
    ) -> DecisionResult:
        """Advance every row by one decision with maneuver ``action`` (int64, batch shape).

        Rows with ``active=False`` are left unchanged (used to freeze finished episodes).
        """
        controls = (self.controls.axial_excess[action], self.controls.normal_load[action],
                    self.controls.turn_direction[action])
        return self._decide(self._substeps, aircraft_state, destination_state, destination_speed,
                            destination_turn_rate, controls, active, (self.params, self.substeps_per_call))

    def fly_targets(
        self,
        aircraft_state: torch.Tensor,
        destination_state: torch.Tensor,
        destination_speed: torch.Tensor,
        destination_turn_rate: torch.Tensor,
        held_targets: torch.Tensor,
        active: torch.Tensor | None = None,
    ) -> DecisionResult:
        """Advance every row by one decision with the autopilot (:mod:`agrl.core.autopilot`) flying
        ``held_targets`` (``(..., 3)``: heading rad, altitude m, speed m/s); needs ``autopilot``. Rows with
        ``active=False`` are left unchanged. Compiled like the maneuvers' step (its own kept compilation, made on
        the first call)."""
        if self.autopilot is None:
            raise ValueError("fly_targets needs a DecisionSimulator built with autopilot=AutopilotParameters(...)")
        targets = tuple(field.contiguous() for field in held_targets.unbind(-1))
        return self._decide(self._targets_step(), aircraft_state, destination_state, destination_speed,
                            destination_turn_rate, targets, active,
                            (self.params, self.autopilot, self.substeps_per_call))

    def _decide(self, run, aircraft_state, destination_state, destination_speed, destination_turn_rate, controls,
                active, constants) -> DecisionResult:
        """One decision: ``run`` (a substeps function) ``substeps // substeps_per_call`` times with the per-row
        ``controls`` and the trailing ``constants``, then the headings wrapped."""
        # Contiguous fields: the fused step then sees the same strides at every substep (no recompilation).
        aircraft = AircraftState(*(field.contiguous() for field in aircraft_state.unbind(-1)))
        destination = DestinationState(*(field.contiguous() for field in destination_state.unbind(-1)))
        shape, device = aircraft.x.shape, aircraft.x.device
        if active is None:
            active = torch.ones(shape, dtype=torch.bool, device=device)
        outcome = torch.full(shape, int(Outcome.RUNNING), dtype=torch.int64, device=device)
        # One call's results are the next call's leading arguments: run.repeat checks torch's guards on the first
        # call of the decision only (agrl.core.compiled.CachedRowwiseCompile.repeat).
        aircraft, destination, active, outcome = run.repeat(
            self.substeps // self.substeps_per_call, aircraft, destination, active, outcome, destination_speed,
            destination_turn_rate, *controls, *constants,
        )
        aircraft = aircraft._replace(heading=wrap_angle(aircraft.heading))
        destination = destination._replace(heading=wrap_angle(destination.heading))
        return DecisionResult(aircraft.to_tensor(), destination.to_tensor(), outcome)

    def _targets_step(self) -> EagerFallback:
        if self._targets_run is None:
            compiled = _target_substeps
            if self._compile:
                compiled = CachedRowwiseCompile(
                    _target_substeps, "simulation step (targets)",
                    key=f"{self.params!r} {self.autopilot!r} x{self.substeps_per_call}", options=_INDUCTOR_OPTIONS)
            self._targets_run = EagerFallback(compiled, _target_substeps, "the simulation step (targets)")
        return self._targets_run
