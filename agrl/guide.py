"""A trained agent as a plain function from the raw state to a maneuver, for use outside training.

::

    from agrl.guide import Guide
    guide = Guide.load("baseline")          # or a checkpoint, a run directory, a .onnx or .pt2 export
    maneuver = guide.instruct((x, y, z, v, theta, psi, phi), (x_d, y_d, z_d, psi_d), last_action)   # int
    maneuvers = guide.instruct_batch(aircraft (N, 7), destination (N, 4), last_actions (N,))      # (N,) int64

The raw state is the environment's (``info["aircraft_state"]``, ``info["destination_state"]`` and the
maneuver being flown; metres, m/s, radians). The answer is the TorchRL actor's deterministic action
(the argmax of its logits, :func:`agrl.rl.models.make_actor`), and the observation is
:func:`agrl.core.observation.policy_observation` with the airspace and aircraft limits the agent was
trained with:

- from a checkpoint, ``instruct_batch`` runs that function and the actor's layers in torch as
  :class:`BatchedLayers` (in-place activations into reused buffers; tested equal to the actor);
  ``instruct`` (one query, where torch's per-operation cost would dominate) runs the one-row form
  :func:`agrl.rows.observation_row` (tested equal to it) and three numpy matrix-vector products;
- an ONNX (``onnxruntime``) or ``torch.export`` file holds :class:`GuidePolicy`: the same observation
  function, network and argmax as one graph with raw-state inputs ``aircraft_state`` ``(N, 7)``
  float32, ``destination_state`` ``(N, 4)`` float32, ``last_action`` ``(N,)`` int64 and output
  ``maneuver`` ``(N,)`` int64, so it runs without agrl. Write them with ``python -m agrl.export``.

Checkpoints are read with :func:`agrl.rl.checkpoint.load_checkpoint` (no code-executing unpickling).
"""

from __future__ import annotations

import dataclasses
import json
import math
import threading
from collections.abc import Mapping, Sequence, Set
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn

from agrl.config import one_line
from agrl.core.aircraft import MANEUVER_NAMES, AircraftLimits
from agrl.core.observation import policy_observation, target_observation_function
from agrl.core.parameters import ActionKind, ActionSet
from agrl.core.termination import Airspace
from agrl.plan import Plan, plan, task_parameters
from agrl.rows import observation_row

NUM_MANEUVERS = len(MANEUVER_NAMES)
FLOAT32_MAX = float(np.finfo(np.float32).max)
#: Key of the JSON metadata (airspace, limits, source) stored in ONNX and torch.export files.
METADATA_KEY = "agrl_guide"
INPUT_NAMES = ("aircraft_state", "destination_state", "last_action")
OUTPUT_NAME = "maneuver"
#: An agent holding targets (``actions=targets``) reads the held targets (heading rad, altitude m, speed m/s) where a
#: maneuver agent reads its last maneuver, and answers an action of its table.
TARGET_INPUT_NAMES = ("aircraft_state", "destination_state", "held_targets")
TARGET_OUTPUT_NAME = "action"
#: What a guide exported before action sets existed flies: the paper's maneuvers.
MANEUVERS = ActionSet(ActionKind.MANEUVERS)
_ACTIVATIONS = {"tanh": np.tanh, "relu": lambda value: np.maximum(value, 0.0),
                "elu": lambda value: np.where(value > 0, value, np.expm1(np.minimum(value, 0.0)))}


def _tanh_(value: torch.Tensor) -> torch.Tensor:
    """tanh in place, as 2 sigmoid(2x) - 1: the same function, and torch's CPU sigmoid kernel is several times
    faster than its tanh kernel (0.04 against 0.2 us per 128-wide row on the project's 2-core machine)."""
    return torch.sigmoid(value.mul_(2.0), out=value).mul_(2.0).sub_(1.0)


_ACTIVATIONS_IN_PLACE = {"tanh": _tanh_, "relu": torch.relu_, "elu": torch.nn.functional.elu_}


class GuideError(ValueError):
    """A guide cannot be loaded or was asked a malformed question; the message names the value."""


class GuidePolicy(nn.Module):
    """Raw state -> action index: the relative observation, the actor's network, argmax (deterministic action).

    A maneuver agent's third input is the maneuver flown (``last_action``, int64); an agent holding targets
    (``actions.holds_targets``) reads the held targets ``(N, 3)`` float32 there instead."""

    def __init__(self, network: nn.Module, airspace: Airspace, limits: AircraftLimits,
                 actions: ActionSet = MANEUVERS):
        super().__init__()
        self.network = network
        self.airspace = airspace
        self.limits = limits
        self.actions = actions
        self._observation = (target_observation_function("relative") if actions.holds_targets
                             else policy_observation)

    def observe(self, aircraft_state: torch.Tensor, destination_state: torch.Tensor,
                last_action: torch.Tensor) -> torch.Tensor:
        """The network's input from the raw state (``last_action``: the held targets for an agent holding them)."""
        return self._observation(aircraft_state, destination_state, last_action, self.airspace, self.limits)

    def forward(self, aircraft_state: torch.Tensor, destination_state: torch.Tensor,
                last_action: torch.Tensor) -> torch.Tensor:
        return self.network(self.observe(aircraft_state, destination_state, last_action)).argmax(-1)


class BatchedLayers:
    """The actor's network (Linear layers with one activation between them) for batched inference.

    The same function as the TorchRL actor's network, computed with ``torch.addmm`` into output buffers kept per
    batch size and activations applied in place: at 4 096 rows a fresh 2 MB tensor per layer and torch's tanh
    kernel cost about as much as the matrix products (``make bench``'s ``guide_batch_us_per_query``). Buffers are
    per thread, so one guide may answer several threads at once.
    """

    def __init__(self, network: nn.Module, activation: str):
        linear = [module for module in network.modules() if isinstance(module, nn.Linear)]
        # Transposed views: addmm(bias, input, weight.T) is Linear's own formula.
        self.layers = [(layer.weight.detach().t(), layer.bias.detach()) for layer in linear]
        self.activation = _ACTIVATIONS_IN_PLACE[activation]
        self._local = threading.local()

    def _buffers(self, rows: int) -> list[torch.Tensor]:
        buffers = getattr(self._local, "buffers", None)
        if buffers is None or buffers[0].shape[0] != rows:
            buffers = [torch.empty(rows, weight.shape[1], dtype=weight.dtype) for weight, _ in self.layers]
            self._local.buffers = buffers
        return buffers

    def __call__(self, observation: torch.Tensor) -> torch.Tensor:
        """Logits ``(N, 7)`` for observations ``(N, OBSERVATION_SIZE)`` (a buffer: read it before the next call)."""
        value = observation
        last = len(self.layers) - 1
        for index, ((weight, bias), buffer) in enumerate(zip(self.layers, self._buffers(len(observation)),
                                                              strict=True)):
            value = torch.addmm(bias, value, weight, out=buffer)
            if index < last:
                self.activation(value)
        return value


def _metadata(airspace: Airspace, limits: AircraftLimits, source: str, actions: ActionSet = MANEUVERS) -> str:
    return json.dumps({"airspace": dataclasses.asdict(airspace), "limits": dataclasses.asdict(limits),
                       "source": source, "actions": dataclasses.asdict(actions)})


def _from_metadata(text: str, path: Path) -> tuple[Airspace, AircraftLimits, str, ActionSet]:
    try:
        values = json.loads(text)
        limits = dict(values["limits"])
        if "max_flight_path_angle" in limits:  # an export written when the limit was stored in radians
            limits["max_flight_path_angle_deg"] = math.degrees(limits.pop("max_flight_path_angle"))
        actions = ActionSet(**values["actions"]) if "actions" in values else MANEUVERS
        return (Airspace(**values["airspace"]), AircraftLimits(**limits), values.get("source", str(path)),
                actions)
    except (ValueError, KeyError, TypeError) as error:
        raise GuideError(f"{path}: not an agrl guide export (bad {METADATA_KEY} metadata: {error})") from None


def load_policy(reference: str | Path = "baseline") -> tuple[GuidePolicy, str, str]:
    """(:class:`GuidePolicy`, activation name, checkpoint path) of a shipped agent, a checkpoint or a run directory."""
    from agrl.config import saved_agent_config, saved_guidance_parameters
    from agrl.rl.models import load_agent

    actor, saved, path = load_agent(str(reference))
    observation = saved_agent_config(saved).observation
    if observation != "relative":
        # The guide's single-query path, ONNX and torch.export graphs compute the relative observation only.
        raise GuideError(f"{path}: agent.observation={observation} is not allowed for a guide or an export: "
                         "relative only (evaluate this agent with python -m agrl.evaluate)")
    params = saved_guidance_parameters(saved)
    networks = [module for module in actor.modules() if isinstance(module, nn.Sequential)]
    policy = GuidePolicy(networks[0], params.simulation.airspace, params.simulation.limits, params.actions).eval()
    return policy, saved["agent"]["activation"], str(path)


def _array(values, name: str) -> np.ndarray:
    """``np.asarray(values)``, or :class:`GuideError` naming ``values`` if they nest raggedly."""
    try:
        return np.asarray(values)
    except ValueError:
        raise GuideError(f"{name}={one_line(values)} is not allowed: an array (ragged nesting)") from None


def _rows(values, width: int, name: str) -> np.ndarray:
    array = _array(values, name)
    if array.ndim != 2 or array.shape[1] != width:
        raise GuideError(f"{name} of shape {array.shape} is not allowed: (N, {width}) finite numbers")
    if array.dtype.kind not in "iuf":  # characters, truth values, None or other objects
        raise GuideError(f"{name} of dtype {array.dtype} is not allowed: (N, {width}) finite numbers")
    with np.errstate(over="ignore"):  # beyond float32's range: not finite, refused below
        array = array.astype(np.float32, copy=False)
    finite = np.isfinite(array).all(axis=1)
    if not finite.all():
        row = int(np.flatnonzero(~finite)[0])
        raise GuideError(f"{name}[{row}]={one_line(np.asarray(values)[row].tolist())} is not allowed: (N, {width}) "
                         "finite numbers (float32)")
    return array


def _numbers(values, width: int) -> list[float] | None:
    """``values`` as ``width`` floats finite in float32 (what the guide computes in), or None."""
    try:
        items = list(values)
        if isinstance(values, (str, bytes, Mapping, Set)) or any(
                isinstance(item, (str, bytes, bool, np.bool_)) for item in items):
            return None  # characters, keys, unordered items or truth values: not a state's numbers in order
        numbers = [float(item) for item in items]
    except (TypeError, ValueError, OverflowError):
        return None
    finite = all(math.isfinite(number) and abs(number) <= FLOAT32_MAX for number in numbers)
    return numbers if len(numbers) == width and finite else None


def _actions(values, count: int) -> np.ndarray:
    """A maneuver agent's third input: the maneuvers flown, ``(count,)`` int64."""
    array = _array(values, "last_action")
    if (array.shape != (count,) or not np.issubdtype(array.dtype, np.integer)
            or not bool(((array >= 0) & (array < NUM_MANEUVERS)).all())):
        raise GuideError(f"last_action of shape {array.shape} and dtype {array.dtype} is not allowed: "
                         f"({count},) integers in [0, {NUM_MANEUVERS - 1}]")
    return array.astype(np.int64, copy=False)


class Guide:
    """A trained agent answering "which maneuver now?" (or, for an agent holding targets, "which clearance
    now?"); build it with :meth:`Guide.load`.

    ``actions`` is the agent's action set (:class:`agrl.core.parameters.ActionSet`). For an agent holding targets
    (``actions.holds_targets``), the third argument of :meth:`instruct` and :meth:`instruct_batch` is the targets
    held now (heading rad, altitude m, speed m/s; at the start what the aircraft flies) instead of the maneuver
    flown, and the answer is an index of :attr:`target_table`."""

    def __init__(self, airspace: Airspace, limits: AircraftLimits, source: str, kind: str,
                 policy: GuidePolicy | None = None, activation: str = "tanh", runner=None,
                 actions: ActionSet = MANEUVERS):
        self.airspace, self.limits, self.source, self.kind = airspace, limits, source, kind
        self.actions = policy.actions if policy is not None else actions
        self.policy = policy  # the torch GuidePolicy (checkpoint and torch_export kinds)
        self._runner = runner  # an onnxruntime session or a torch.export module
        self._layers: list[tuple[np.ndarray, np.ndarray]] = []
        self._batched: BatchedLayers | None = None
        if policy is not None and kind == "checkpoint":
            self._batched = BatchedLayers(policy.network, activation)
            if not self.holds_targets:  # the one-row numpy path computes the maneuver agent's observation
                self._layers = [(weight.t().numpy().copy(), bias.numpy().copy())
                                for weight, bias in self._batched.layers]
            self._activation = _ACTIVATIONS[activation]

    @property
    def holds_targets(self) -> bool:
        return self.actions.holds_targets

    @property
    def target_table(self):
        """The target-holding actions (:class:`agrl.core.autopilot.TargetActionTable`), None for a maneuver agent."""
        return self.actions.target_table(self.airspace, self.limits)

    @property
    def num_actions(self) -> int:
        return self.actions.count(self.airspace, self.limits)

    # ------------------------------------------------------------------ loading
    @classmethod
    def load(cls, reference: str | Path = "baseline") -> Guide:
        """A shipped agent's name (``baseline``, ...), a checkpoint file or run directory, or an export (``.onnx``,
        ``.pt2``)."""
        path = Path(reference)
        if path.suffix == ".onnx":
            return cls._load_onnx(path)
        if path.suffix == ".pt2":
            return cls._load_torch_export(path)
        policy, activation, source = load_policy(reference)
        return cls(policy.airspace, policy.limits, source, "checkpoint", policy, activation)

    @classmethod
    def _load_onnx(cls, path: Path) -> Guide:
        try:
            import onnxruntime
        except ImportError:
            raise GuideError(f"{path}: running an ONNX guide needs onnxruntime (pip install 'agrl[export]')") from None
        if not path.is_file():
            raise GuideError(f"{path}: no such ONNX file")
        options = onnxruntime.SessionOptions()
        options.intra_op_num_threads = 1  # one query is far below the cost of waking threads
        try:
            session = onnxruntime.InferenceSession(str(path), options, providers=["CPUExecutionProvider"])
        except Exception as error:  # onnxruntime raises its own types for foreign or corrupt files
            raise GuideError(f"{path}: not a readable ONNX model: {str(error).splitlines()[0]}") from None
        metadata = session.get_modelmeta().custom_metadata_map
        if METADATA_KEY not in metadata:
            raise GuideError(f"{path}: not an agrl guide export (no {METADATA_KEY} metadata)")
        airspace, limits, source, actions = _from_metadata(metadata[METADATA_KEY], path)
        return cls(airspace, limits, source, "onnx", runner=session, actions=actions)

    @classmethod
    def _load_torch_export(cls, path: Path) -> Guide:
        if not path.is_file():
            raise GuideError(f"{path}: no such torch.export file")
        extra = {METADATA_KEY: ""}
        try:
            program = torch.export.load(str(path), extra_files=extra)
        except Exception as error:  # torch raises many types for foreign or corrupt archives
            raise GuideError(f"{path}: not a readable torch.export archive: {str(error).splitlines()[0]}") from None
        if not extra[METADATA_KEY]:
            raise GuideError(f"{path}: not an agrl guide export (no {METADATA_KEY} metadata)")
        airspace, limits, source, actions = _from_metadata(extra[METADATA_KEY], path)
        return cls(airspace, limits, source, "torch_export", runner=program.module(), actions=actions)

    # ------------------------------------------------------------------ questions
    def instruct(self, aircraft_state, destination_state, last_action) -> int:
        """The maneuver index for one aircraft (x, y, z, v, theta, psi, phi) and destination (x, y, z, psi);
        for an agent holding targets, the action index, ``last_action`` being the held targets (3 numbers)."""
        aircraft, destination = _numbers(aircraft_state, 7), _numbers(destination_state, 4)
        if aircraft is None or destination is None:
            raise GuideError(f"aircraft_state={one_line(aircraft_state)}, destination_state="
                             f"{one_line(destination_state)} are not allowed: 7 and 4 finite numbers (float32)")
        if self.holds_targets:
            held = _numbers(last_action, 3)
            if held is None:
                raise GuideError(f"held_targets={one_line(last_action)} is not allowed: 3 finite numbers (heading "
                                 "rad, altitude m, speed m/s)")
            return int(self._run(np.array([aircraft], np.float32), np.array([destination], np.float32),
                                 np.array([held], np.float32))[0])
        if isinstance(last_action, bool) or not isinstance(last_action, (int, np.integer)) or not (
                0 <= last_action < NUM_MANEUVERS):
            raise GuideError(f"last_action={one_line(last_action)} is not allowed: an integer in "
                             f"[0, {NUM_MANEUVERS - 1}]")
        if not self._layers:
            return int(self._run(np.array([aircraft], np.float32), np.array([destination], np.float32),
                                 np.array([last_action], np.int64))[0])
        value = np.array(observation_row(aircraft, destination, int(last_action), self.airspace, self.limits),
                         dtype=np.float32)
        for weight, bias in self._layers[:-1]:
            value = self._activation(weight @ value + bias)
        weight, bias = self._layers[-1]
        return int(np.argmax(weight @ value + bias))

    def instruct_batch(self, aircraft_state, destination_state, last_action) -> np.ndarray:
        """Maneuver indices ``(N,)`` int64 for aircraft ``(N, 7)``, destinations ``(N, 4)``, last actions ``(N,)``."""
        aircraft = _rows(aircraft_state, 7, "aircraft_state")
        destination = _rows(destination_state, 4, "destination_state")
        if destination.shape[0] != aircraft.shape[0]:
            raise GuideError(f"destination_state of shape {destination.shape} is not allowed: one row per aircraft "
                             f"({aircraft.shape[0]})")
        if self.holds_targets:
            held = _rows(last_action, 3, "held_targets")
            if held.shape[0] != aircraft.shape[0]:
                raise GuideError(f"held_targets of shape {held.shape} is not allowed: one row per aircraft "
                                 f"({aircraft.shape[0]})")
            return self._run(aircraft, destination, held)
        return self._run(aircraft, destination, _actions(last_action, aircraft.shape[0]))

    def _run(self, aircraft: np.ndarray, destination: np.ndarray, last_action: np.ndarray) -> np.ndarray:
        if self.kind == "onnx":
            names, output = ((TARGET_INPUT_NAMES, TARGET_OUTPUT_NAME) if self.holds_targets
                             else (INPUT_NAMES, OUTPUT_NAME))
            inputs = dict(zip(names, (aircraft, destination, last_action), strict=True))
            return self._runner.run([output], inputs)[0]
        inputs = torch.from_numpy(aircraft), torch.from_numpy(destination), torch.from_numpy(last_action)
        with torch.inference_mode():  # no autograd bookkeeping at all (no_grad still counts tensor versions)
            if self._batched is None:
                return self._runner(*inputs).numpy()
            observation = self.policy.observe(*inputs)
            return self._batched(observation).argmax(-1).numpy()

    def plan(self, aircraft_state, destination_state=None, task: Sequence[str] = (), last_action: int = 0) -> Plan:
        """The instructions this agent gives from a start, in order with their times, with the trajectory and the
        outcome (:func:`agrl.plan.plan`): ``aircraft_state`` (x, y, z, v, theta, psi, phi), ``destination_state``
        (x, y, z, psi; default the task's start), ``task`` overrides as ``python -m agrl.evaluate`` takes them
        (``["task=uniform", "speed=50"]``; default the agent's own task); ``last_action``: the maneuver flown at the
        start (a maneuver agent's)."""
        return plan(self, task_parameters(self, task), aircraft_state, destination_state, last_action)

    def __repr__(self) -> str:
        return f"Guide(kind={self.kind!r}, source={self.source!r})"


def example_inputs(count: int = 2, holds_targets: bool = False) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Raw-state inputs of the right shapes and dtypes (for tracing an export)."""
    aircraft = torch.zeros(count, 7)
    aircraft[:, 3] = 200.0
    if holds_targets:
        return aircraft, torch.zeros(count, 4), aircraft[:, [5, 2, 3]].clone()
    return aircraft, torch.zeros(count, 4), torch.zeros(count, dtype=torch.int64)


def io_names(policy: GuidePolicy) -> tuple[tuple[str, ...], str]:
    """An export's input names and output name for ``policy``'s action set."""
    if policy.actions.holds_targets:
        return TARGET_INPUT_NAMES, TARGET_OUTPUT_NAME
    return INPUT_NAMES, OUTPUT_NAME


def export_metadata(policy: GuidePolicy, source: str) -> dict[str, Any]:
    """``{METADATA_KEY: json}``: what :meth:`Guide.load` needs beside the graph (airspace, limits, source, action
    set)."""
    return {METADATA_KEY: _metadata(policy.airspace, policy.limits, source, policy.actions)}
