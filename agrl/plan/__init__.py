"""An instruction plan: what a trained agent would tell an aircraft, in order, from a start to the end of the flight.

::

    python -m agrl.plan --aircraft -6000 3000 2500 200 0 0 0                     # the shipped baseline, fixed task
    python -m agrl.plan --aircraft -6000 3000 2500 200 0 0 0 task=uniform speed=50 --figure plan.png
    python -m agrl.plan --aircraft ... --destination 2000 0 1000 0 --checkpoint runs/... --json

    from agrl.guide import Guide
    guide = Guide.load("baseline")
    result = guide.plan((x, y, z, v, theta, psi, phi), task=["task=uniform", "speed=50"])
    for instruction in result.instructions:
        print(instruction.time_s, instruction.text)          # 0.0 left turn (2 g) ...

The flight is the single gymnasium env's (:mod:`agrl.envs.gym`): at each 3 s decision the guide picks the maneuver
(:meth:`agrl.guide.Guide.instruct`), :func:`agrl.reference.reference_decision` flies it and moves the destination
by the task's motion model, until success, leaving the airspace or the decision budget. An *instruction* is a
decision whose maneuver differs from the one being flown, the aircraft starting in steady flight: the evaluation's
count (:mod:`agrl.rl.evaluation`). The task (load factors, tolerances, budget, destination motion) is a checkpoint's
own saved one, with ``python -m agrl.evaluate``'s task overrides (``task=uniform speed=50``); an ONNX or
``torch.export`` file carries only the airspace and limits, so ``conf/``'s defaults and the overrides serve there.
An irregular destination is refused: its motion is random, so no plan can say where it will be.

:meth:`agrl.guide.Guide.plan` is :func:`plan` with that guide; :mod:`agrl.plan.figure` draws a plan and
``python -m agrl.plan`` (:mod:`agrl.plan.__main__`) is the command line.
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import torch

from agrl.config import (
    compose_checked,
    guidance_parameters,
    load_config,
    one_line,
    override_key,
    saved_guidance_parameters,
)
from agrl.core.aircraft import MANEUVER_NAMES, AircraftState
from agrl.core.autopilot import HeldTargets, TargetKind, apply_target_action, target_instruction_text
from agrl.core.parameters import GuidanceParameters, ManeuverLoadFactors, MotionKind
from agrl.core.simulation import DecisionSimulator
from agrl.core.termination import Outcome
from agrl.reference import maneuver_rows, reference_decision

#: The task overrides a plan takes (``python -m agrl.evaluate``'s): the task, its shorthands and its keys.
TASK_OVERRIDES = ("task", "speed", "radius")
AIRCRAFT_FIELDS = ("x", "y", "z", "v", "theta", "psi", "phi")
DESTINATION_FIELDS = ("x", "y", "z", "psi")
FLOAT32_MAX = 3.4028234663852886e38  # the guide computes in float32


class PlanError(ValueError):
    """A plan was asked for with a bad value; the message (one line) names it and what is allowed."""


@dataclass(frozen=True)
class Instruction:
    """One instruction: when it is given (s from the start), the action, and where the aircraft is then (m)."""

    time_s: float
    maneuver: int  # the action's index: a maneuver, or for an agent holding targets a row of its target table
    name: str  # MANEUVER_NAMES' entry; for a target: heading, altitude, speed or hold
    text: str  # what a controller says: "left turn (2 g)", "turn left heading 270", "climb to 3 000 m"
    position: tuple[float, float, float]


@dataclass(frozen=True)
class Trajectory:
    """The flight at each decision: ``time_s``, aircraft (x, y, z, v, theta, psi, phi) and destination (x, y, z,
    psi) at the start and after each decision (decisions + 1 rows), and the action taken at each decision (the
    maneuver flown, or the target-holding action)."""

    time_s: list[float]
    aircraft: list[tuple[float, ...]]
    destination: list[tuple[float, ...]]
    maneuvers: list[int]


@dataclass(frozen=True)
class Plan:
    """The instructions in order, the flight, and how it ended (``success``, ``out_of_airspace`` or
    ``budget_exhausted``: the evaluation's names) after ``flight_time_s`` seconds and ``decisions`` decisions."""

    instructions: list[Instruction]
    trajectory: Trajectory
    outcome: str
    flight_time_s: float
    decisions: int

    def as_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)

    def to_json(self, indent: int | None = None) -> str:
        return json.dumps(self.as_dict(), indent=indent)

    def lines(self) -> list[str]:
        """One line per instruction (``t=   0 s  left turn (2 g)``), then the outcome."""
        lines = [f"t={instruction.time_s:4.0f} s  {instruction.text}" for instruction in self.instructions]
        count = len(self.instructions)
        lines.append(f"{self.outcome.replace('_', ' ')} after {self.flight_time_s:.0f} s ({self.decisions} decisions, "
                     f"{count} instruction{'s' if count != 1 else ''})")
        return lines


def maneuver_text(maneuver: int, maneuvers: ManeuverLoadFactors) -> str:
    """What a controller says for a maneuver: its name with the load factor its control law holds
    (``left turn (2 g)``, ``accelerate (0.3 g)``; ``steady flight`` has none)."""
    axial_excess, normal_load, _ = maneuver_rows(maneuvers)[maneuver]
    words = MANEUVER_NAMES[maneuver].replace("_", " ")
    load = abs(axial_excess) if axial_excess != 0.0 else normal_load
    return words if load is None else f"{words} ({load:g} g)"


# ---------------------------------------------------------------------------- the task
def task_parameters(guide, overrides: Sequence[str] = ()) -> GuidanceParameters:
    """The task a plan flies: a checkpoint's own saved one, or ``conf/``'s for an export (whose airspace and limits
    it keeps), with task overrides as ``python -m agrl.evaluate`` takes them (``task=uniform``, ``speed=50``,
    ``radius=...``, ``task.<key>=...``). :class:`agrl.config.ConfigError` or :class:`PlanError` (one line)."""
    overrides = list(overrides)
    for override in overrides:
        key = override_key(override)
        if "=" not in override or not (key in TASK_OVERRIDES or key.startswith("task.")):
            raise PlanError(f"{override} is not allowed: a task override (task=..., speed=..., radius=... or "
                            "task.<key>=...)")
    task = load_config(compose_checked(*overrides, "checkpoint=plan", config_name="evaluate")).task
    if guide.kind == "checkpoint":
        from agrl.rl.checkpoint import load_checkpoint, resolve_checkpoint_path

        saved = load_checkpoint(resolve_checkpoint_path(guide.source), required=("config",))["config"]
        return saved_guidance_parameters(saved, task, compile=False)
    params = guidance_parameters(*overrides)
    simulation = dataclasses.replace(params.simulation, airspace=guide.airspace, limits=guide.limits)
    return dataclasses.replace(params, simulation=simulation, actions=guide.actions)


def state_numbers(values, fields: tuple[str, ...], name: str) -> tuple[float, ...]:
    """``values`` as len(fields) finite floats, or :class:`PlanError` naming them."""
    allowed = f"{len(fields)} finite numbers ({' '.join(field.upper() for field in fields)})"
    try:
        if isinstance(values, (str, bytes)):
            raise TypeError
        numbers = tuple(float(value) for value in values)
    except (TypeError, ValueError, OverflowError):
        raise PlanError(f"{name}={one_line(values)} is not allowed: {allowed}") from None
    if len(numbers) != len(fields):
        raise PlanError(f"{name} of {len(numbers)} numbers is not allowed: {allowed}")
    for field, number in zip(fields, numbers, strict=True):
        if not (math.isfinite(number) and abs(number) <= FLOAT32_MAX):
            raise PlanError(f"{name} {field.upper()}={number} is not allowed: {allowed}, in float32's range")
    return numbers


def _require_inside(name: str, field: str, value: float, low: float, high: float, what: str) -> None:
    if not low <= value <= high:
        raise PlanError(f"{name} {field.upper()}={value:g} is not allowed: {what}")


def checked_states(params: GuidanceParameters, aircraft_state, destination_state,
                   names: tuple[str, str] = ("aircraft_state", "destination_state")) -> tuple[tuple, tuple]:
    """The start as floats, or :class:`PlanError` naming the first bad value: counts, finite numbers, positions
    inside the airspace, the aircraft's speed and flight-path angle within its limits (those the simulator takes),
    and a destination whose motion is known in advance."""
    if params.destination.name is MotionKind.IRREGULAR:
        raise PlanError("task=irregular is not allowed: a plan needs a destination whose motion is known in "
                        "advance (fixed, uniform or curved)")
    aircraft = state_numbers(aircraft_state, AIRCRAFT_FIELDS, names[0])
    destination = state_numbers(destination_state, DESTINATION_FIELDS, names[1])
    space, limits = params.simulation.airspace, params.simulation.limits
    for name, state in ((names[0], aircraft), (names[1], destination)):
        for field, value, low, high in zip("xyz", state[:3], (space.x_min, space.y_min, space.z_min),
                                           (space.x_max, space.y_max, space.z_max), strict=True):
            _require_inside(name, field, value, low, high, f"inside the airspace, {field} in [{low:g}, {high:g}] m")
    _require_inside(names[0], "v", aircraft[3], limits.min_speed, limits.max_speed,
                    f"the aircraft's speed limits [{limits.min_speed:g}, {limits.max_speed:g}] m/s")
    angle = limits.max_flight_path_angle
    _require_inside(names[0], "theta", aircraft[4], -angle, angle,
                    f"the aircraft's flight-path angle limits [{-angle:.4g}, {angle:.4g}] rad")
    return aircraft, destination


# ---------------------------------------------------------------------------- the flight
def plan(guide, params: GuidanceParameters, aircraft_state, destination_state=None, last_action: int = 0) -> Plan:
    """Fly ``guide`` from ``aircraft_state`` (x, y, z, v, theta, psi, phi; m, m/s, rad) towards
    ``destination_state`` (x, y, z, psi; default the task's start) on the task ``params`` (e.g.
    :func:`task_parameters`), the aircraft flying maneuver ``last_action`` (0, steady flight) at the start."""
    if destination_state is None:
        destination_state = params.destination.start
    aircraft, destination = checked_states(params, aircraft_state, destination_state)
    speed, turn_rate = (float(value[0]) for value in params.destination.initial_motion(1, None, "cpu"))
    holds_targets = getattr(guide, "holds_targets", False)  # any object with instruct() is a guide (maneuvers)
    fly = (_target_flight if holds_targets else _maneuver_flight)(guide, params, aircraft, destination, speed,
                                                                  turn_rate, last_action)
    times, aircraft_path, destination_path, actions = [0.0], [aircraft], [destination], []
    instructions, flight_time, outcome = [], 0.0, Outcome.BUDGET_EXHAUSTED
    for decision in range(params.max_decisions):
        action, said, (aircraft, destination, seconds, ended) = fly(aircraft, destination)
        if said is not None:
            instructions.append(Instruction(decision * params.simulation.decision_period, action, *said,
                                            tuple(aircraft_path[-1][:3])))
        flight_time += seconds
        times.append(flight_time)
        aircraft_path.append(aircraft)
        destination_path.append(destination)
        actions.append(action)
        if ended != Outcome.RUNNING:
            outcome = Outcome(ended)
            break
    trajectory = Trajectory(times, aircraft_path, destination_path, actions)
    return Plan(instructions, trajectory, outcome.name.lower(), flight_time, len(actions))


#: One decision of a flight: ``fly(aircraft, destination) -> (action, (name, text) if it is an instruction else None,
#: (aircraft after, destination after, seconds flown, outcome code))``, the aircraft and destination as tuples.
Flight = Callable[[tuple, tuple], tuple[int, tuple[str, str] | None, tuple[tuple, tuple, float, int]]]


def _maneuver_flight(guide, params: GuidanceParameters, aircraft: tuple, destination: tuple, speed: float,
                     turn_rate: float, last_action: int) -> Flight:
    """The single gymnasium env's flight: the guide's maneuver, flown by :func:`agrl.reference.reference_decision`;
    an instruction is a change of maneuver, the aircraft flying ``last_action`` at the start."""
    simulation, loads = params.simulation, params.maneuvers
    flying = [last_action]

    def fly(aircraft: tuple, destination: tuple):
        maneuver = guide.instruct(aircraft, destination, flying[0])
        said = (MANEUVER_NAMES[maneuver], maneuver_text(maneuver, loads)) if maneuver != flying[0] else None
        result = reference_decision(aircraft, destination, speed, turn_rate, maneuver, simulation, loads)
        flying[0] = maneuver
        return maneuver, said, (result.aircraft_state, result.destination_state,
                                result.substeps * simulation.integration_step, result.outcome)

    return fly


def _target_flight(guide, params: GuidanceParameters, aircraft: tuple, destination: tuple, speed: float,
                   turn_rate: float, last_action: int) -> Flight:
    """An agent holding targets: the aircraft starts holding what it flies; each decision the guide picks an
    action, the autopilot flies the targets it leaves (:meth:`DecisionSimulator.fly_targets`, one float32 row,
    eager), and an action that changes a target is an instruction. A flight counts whole decisions: the batched
    simulator does not say at which step it ended."""
    simulation = params.simulation
    simulator = DecisionSimulator(simulation, params.maneuvers.controls(),
                                  autopilot=params.actions.autopilot(params.maneuvers))
    table = params.actions.target_table(simulation.airspace, simulation.limits)
    rows = [torch.tensor([aircraft], dtype=torch.float32), torch.tensor([destination], dtype=torch.float32)]
    held = [HeldTargets.of(AircraftState.from_tensor(rows[0]))]
    motion = torch.tensor([speed]), torch.tensor([turn_rate])

    def fly(aircraft: tuple, destination: tuple):
        action = guide.instruct(aircraft, destination, [float(value) for value in held[0]])
        held[0], changed = apply_target_action(held[0], torch.tensor([action]), table)
        said = None
        if bool(changed):
            kind, value = TargetKind(int(table.kind[action])), float(table.value[action])
            said = kind.name.lower(), target_instruction_text(kind, value, AircraftState.from_tensor(rows[0][0]))
        result = simulator.fly_targets(*rows, *motion, torch.stack(tuple(held[0]), dim=-1))
        rows[:] = result.aircraft_state, result.destination_state
        return action, said, (tuple(rows[0][0].tolist()), tuple(rows[1][0].tolist()), simulation.decision_period,
                              int(result.outcome[0]))

    return fly
