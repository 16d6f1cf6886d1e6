"""The paper's MDP as a single, unbatched gymnasium environment (fast: one row in Python floats).

``import agrl`` registers it as ``agrl/Guidance-v0``, so any library that trains on gymnasium environments can use
the paper's MDP::

    import gymnasium, agrl
    env = gymnasium.make("agrl/Guidance-v0", task="uniform", speed=50.0)
    obs, info = env.reset(seed=0)
    obs, reward, terminated, truncated, info = env.step(env.action_space.sample())

One row runs in Python floats: the decision is :func:`agrl.reference.reference_decision` (the pure-Python form
of the batched simulator, tested equal to it), the observation and reward are :mod:`agrl.rows`' one-row forms of
:mod:`agrl.core`'s (tested equal to them). Resets, seeding and the irregular destination's random redraws are
those of a one-row :class:`agrl.envs.GuidanceEnv` (same functions, same generator), so from the same seed or
scenario and the same actions the two environments fly the same episodes (``tests/envs/test_gym.py`` states the
float tolerance: the batched env runs float32, this one float64). The many-environment form, which also takes the
target-holding actions, is :mod:`agrl.envs.gym_vector` (``gymnasium.make_vec(..., vectorization_mode=
"vector_entry_point")``). The task parameters are composed from ``conf/`` as ``python -m agrl.train`` does.

Episodes end with ``terminated=True`` on success, on leaving the airspace and when the decision budget is spent:
the budget is part of the paper's MDP (it pays ``reward.budget_exhausted``, c3), not a time limit, so ``truncated``
is always False.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import os
import sys
from collections.abc import Mapping
from typing import Any

import gymnasium
import numpy as np
import torch
from gymnasium import spaces

from agrl.config import ConfigError, config_options, guidance_parameters, one_line
from agrl.core.aircraft import MANEUVER_NAMES
from agrl.core.observation import observation_features
from agrl.core.parameters import MOTION_FIELDS, GuidanceParameters, MotionKind, tasks_taking
from agrl.core.termination import Outcome
from agrl.envs.guidance import NUM_ACTIONS, SCENARIO_KEYS, GuidanceEnv
from agrl.reference import reference_decision
from agrl.rows import initial_aircraft_row, observation_row, potential_row, step_reward_row

ENV_ID = "agrl/Guidance-v0"
_OUTCOME_NAMES = tuple(outcome.name.lower() for outcome in Outcome)  # indexed by the Outcome code

def _fail(name: str, value: Any, allowed: str) -> None:
    raise ValueError(f"{name}={one_line(value)} is not allowed: {allowed}")


#: Seeds both generators take (gymnasium's numpy one and the env's torch one).
SEED_LIMIT = 2**64


def checked_seed(seed: Any, allowed: str = "None or an integer in [0, 2**64 - 1]") -> int | None:
    """``reset(seed=...)`` as a Python int (None stays None); ``ValueError`` naming it if it is no such seed."""
    integral = isinstance(seed, (int, np.integer)) and not isinstance(seed, bool)
    if seed is not None and not (integral and 0 <= seed < SEED_LIMIT):
        _fail("seed", seed, allowed)
    return None if seed is None else int(seed)


def _number(name: str, value: Any, what: str, integral: bool = False) -> float:
    """A keyword argument's type (a Python value is not an override yet): a real number (an integer if
    ``integral``), else ``ValueError`` naming it. Its range is the schema's (:mod:`agrl.config.task`)."""
    real = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool)
    if not real or (integral and not (math.isfinite(value) and value == int(value))):
        _fail(name, value, what)
    return int(value) if integral else float(value)


def gym_parameters(
    task: str = "fixed",
    speed: float | None = None,
    radius: float | None = None,
    turn_direction: int | None = None,
    max_decisions: int | None = None,
    reward: str | None = None,
    compile: bool = False,
    actions: str | None = None,
) -> GuidanceParameters:
    """The :class:`GuidanceParameters` of ``gymnasium.make("agrl/Guidance-v0", **kwargs)``'s keyword arguments: those
    ``python -m agrl.train task=... reward=... actions=...`` would use (``actions``: the vector env's only). Composed
    from ``conf/`` by :func:`agrl.config.guidance_parameters` (Hydra's compose API and the schemas' checks), so every
    default is the YAML's own. Raises ``ValueError`` (one line) naming a bad value and what is allowed: a keyword's type
    is checked here (a Python value is no override yet), its range by the schema.
    """
    tasks, rewards, action_sets = config_options("task"), config_options("reward"), config_options("actions")
    if task not in tasks:
        _fail("task", task, f"one of {', '.join(tasks)}")
    if reward is not None and reward not in rewards:
        _fail("reward", reward, f"one of {', '.join(rewards)} (None: the training default, conf/config.yaml)")
    if not isinstance(compile, bool):
        _fail("compile", compile, "True or False")
    if actions is not None and actions not in action_sets:
        _fail("actions", actions, f"one of {', '.join(action_sets)} (None: the paper's maneuvers)")
    overrides = [f"task={task}", *([f"actions={actions}"] if actions is not None else [])]
    if reward is not None:
        overrides.append(f"reward={reward}")
    given = {"speed": speed, "radius": radius, "turn_direction": turn_direction}
    for name, value in given.items():
        if value is not None and name not in MOTION_FIELDS[task]:
            _fail(name, value, f"task={task} has no destination {name} (only task={' or '.join(tasks_taking(name))})")
    if speed is not None:
        overrides.append(f"speed={_number('speed', speed, f'task={task} needs a destination speed in m/s')!r}")
    if radius is not None:
        overrides.append(f"radius={_number('radius', radius, f'task={task} needs a turning radius in m')!r}")
    if turn_direction is not None:
        direction = _number("turn_direction", turn_direction, "+1 (counter-clockwise) or -1 (clockwise)", True)
        overrides.append(f"task.turn_direction={direction}")
    if max_decisions is not None:
        budget = _number("max_decisions", max_decisions, "an integer >= 1 (decisions of 3 s per episode)", True)
        overrides.append(f"simulation.max_decisions={budget}")
    return _composed_parameters(tuple(overrides), compile)


@functools.lru_cache(maxsize=64)
def _composed_parameters(overrides: tuple[str, ...], compile: bool) -> GuidanceParameters:
    # Composing takes a few tenths of a second; vector envs and SB3's make_vec_env ask for the same task often.
    try:
        return guidance_parameters(*overrides, compile=compile)
    except ConfigError as error:
        raise ValueError(str(error)) from None


#: reset(options=...)'s entries: (numbers per row, 0 for one number; what they are).
SCENARIO_WIDTHS = {
    "aircraft_state": (7, "7 finite numbers per aircraft: x, y, z (m), v (m/s), theta, psi, phi (rad)"),
    "destination_state": (4, "4 finite numbers per destination: x, y, z (m), psi (rad)"),
    "destination_speed": (0, "a finite speed (m/s)"),
    "destination_turn_rate": (0, "a finite turn rate (rad/s)"),
}
#: The largest destination turn rate a scenario may give (rad/s): half a turn per second, far beyond any task's.
MAX_DESTINATION_TURN_RATE = math.pi


def _scenario_ranges(params: GuidanceParameters) -> dict[str, list[tuple[int | None, float, float, str]]]:
    """Per scenario entry, (column or None, low, high, what) of the values the simulator takes: positions inside
    the airspace (equation 1), the aircraft's speed and flight-path angle within its limits, the destination no
    faster than the aircraft can fly. Beyond them an episode means nothing, and float32 overflows to NaN."""
    space, limits = params.simulation.airspace, params.simulation.limits
    box = f"inside the airspace x [{space.x_min:g}, {space.x_max:g}], y [{space.y_min:g}, {space.y_max:g}], " \
          f"z [{space.z_min:g}, {space.z_max:g}] m"
    position = [(0, space.x_min, space.x_max, box), (1, space.y_min, space.y_max, box),
                (2, space.z_min, space.z_max, box)]
    angle = limits.max_flight_path_angle
    return {
        "aircraft_state": [*position, (3, limits.min_speed, limits.max_speed,
                                       f"v in [{limits.min_speed:g}, {limits.max_speed:g}] m/s"),
                           (4, -angle, angle, f"theta in [{-angle:.4g}, {angle:.4g}] rad")],
        "destination_state": position,
        "destination_speed": [(None, 0.0, limits.max_speed, f"in [0, {limits.max_speed:g}] m/s")],
        "destination_turn_rate": [(None, -MAX_DESTINATION_TURN_RATE, MAX_DESTINATION_TURN_RATE,
                                   f"in [-{MAX_DESTINATION_TURN_RATE:.4g}, {MAX_DESTINATION_TURN_RATE:.4g}] rad/s")],
    }


def scenario_reset(env: GuidanceEnv, options: Any):
    """``reset(options=...)``'s initial conditions as a :meth:`GuidanceEnv.scenario` (single and vector env), or
    None for no options (None or an empty dict). Each entry holds one row for every env or a row per env."""
    if options is None or (isinstance(options, Mapping) and not options):
        return None
    keys = f"a dict with aircraft_state and optionally {', '.join(SCENARIO_KEYS[1:])}"
    if not isinstance(options, Mapping) or set(options) - set(SCENARIO_KEYS) or "aircraft_state" not in options:
        _fail("options", options, keys)
    count = env.batch_size.numel()
    rows = "one row" if count == 1 else f"one row for all {count} envs or one per env"
    ranges = _scenario_ranges(env.params)
    values = {}
    for key, value in options.items():
        width, allowed = SCENARIO_WIDTHS[key]
        shapes = {(width,), (1, width), (count, width)} if width else {(), (1,), (count,)}
        try:
            array = None if isinstance(value, (str, bytes)) else np.asarray(value, dtype=np.float32)
        except (TypeError, ValueError, OverflowError):
            array = None
        if array is None or array.shape not in shapes or not np.isfinite(array).all():
            _fail(key, value, f"{allowed}; {rows}")
        for column, low, high, what in ranges[key]:
            inside = array if column is None else array[..., column]
            if not ((inside >= low) & (inside <= high)).all():
                _fail(key, value, what)
        values[key] = torch.as_tensor(array)
    return env.scenario(**values)


def observation_bounds(params: GuidanceParameters) -> tuple[np.ndarray, np.ndarray]:
    """Finite bounds of the relative observation for ``params`` (of either action set): every feature is a
    sine/cosine, a clamped quantity, a position inside the airspace mapped to [-1, 1] or a held target's distance
    over its range; an aircraft is at most one integration step outside the airspace at its end, hence a margin."""
    simulation = params.simulation
    space = simulation.airspace
    width, depth, height = space.x_max - space.x_min, space.y_max - space.y_min, space.z_max - space.z_min
    half_width = 0.5 * max(width, depth)
    overshoot = simulation.limits.max_speed * simulation.integration_step  # m in one integration step
    margin = 2.0 * overshoot / min(width, depth, height) + 1e-3
    reach = math.hypot(width, depth) / half_width + margin  # horizontal distance / half-width
    bounds = {
        "horizontal_distance": (0.0, reach),
        "along_track": (-reach, reach),
        "cross_track": (-reach, reach),
    }
    features = observation_features("relative", params.actions.holds_targets)
    low = np.empty(len(features), dtype=np.float32)
    high = np.empty(len(features), dtype=np.float32)
    for index, name in enumerate(features):
        if name.startswith("last_action_"):
            low[index], high[index] = 0.0, 1.0
        else:
            low[index], high[index] = bounds.get(name, (-1.0 - margin, 1.0 + margin))
    return low, high


def _has_display() -> bool:
    return sys.platform in ("darwin", "win32") or bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


class GuidanceGymEnv(gymnasium.Env):
    """The paper's guidance MDP as an unbatched ``gymnasium.Env`` (``Discrete(7)`` maneuvers).

    Keyword arguments (as ``gymnasium.make("agrl/Guidance-v0", **kwargs)``):

    - ``task``: ``fixed`` (default), ``uniform``, ``curved`` or ``irregular``;
    - ``speed`` (m/s; uniform 50, curved 20), ``radius`` (m; curved, 1000), ``turn_direction`` (curved: +1, -1);
    - ``max_decisions``: the decision budget (default 200, ``conf/simulation/paper.yaml``);
    - ``reward``: ``switch`` (the training default), or Table 3's ``none``, ``continuous``, ``position``, ``both``;
    - ``compile`` and ``actions``: the vector env's (:mod:`agrl.envs.gym_vector`); this env steps one row of the
      maneuvers in Python floats (it ignores ``compile``, and ``actions="targets"`` is a one-line error).

    Seed with ``reset(seed=...)``; start from explicit initial conditions with ``reset(options={"aircraft_state":
    (x, y, z, v, theta, psi, phi), "destination_state": (x, y, z, psi), "destination_speed": m/s,
    "destination_turn_rate": rad/s})`` (missing destination fields take the task's). ``info`` holds ``outcome``
    (``running``, ``success``, ``out_of_airspace``, ``budget_exhausted``), ``aircraft_state`` (x, y, z, v, theta,
    psi, phi), ``destination_state`` (x, y, z, psi), ``step_count``, ``instruction_count`` and ``episode_return``.

    ``render_mode="rgb_array"``: ``render()`` returns a ``(450, 800, 3)`` uint8 frame of the episode so far (3-D
    view with the airspace box and a top view; :func:`agrl.plots.episode_frame`), what
    ``gymnasium.wrappers.RecordVideo`` and stable-baselines3 need. ``render_mode="human"`` shows the frames in a
    matplotlib window at every step and needs a display: without one (no ``DISPLAY`` or ``WAYLAND_DISPLAY`` on
    Linux) ``metadata["render_modes"]`` lists only ``rgb_array`` and the constructor raises ``ValueError`` for
    ``human`` (``gymnasium.make(..., render_mode="human")`` then applies gymnasium's own ``HumanRendering`` wrapper,
    which needs pygame and a display).
    """

    # "human" is offered only where a window can open (gymnasium's checker tries every listed mode).
    metadata = {"render_modes": ["rgb_array", "human"] if _has_display() else ["rgb_array"], "render_fps": 4}

    def __init__(
        self,
        task: str = "fixed",
        speed: float | None = None,
        radius: float | None = None,
        turn_direction: int | None = None,
        max_decisions: int | None = None,
        reward: str | None = None,
        compile: bool = False,
        render_mode: str | None = None,
        actions: str | None = None,
    ):
        if actions not in (None, "maneuvers"):  # one row in Python floats: the maneuvers' reference forms only
            _fail("actions", actions, "None or 'maneuvers' for the single env; targets: gymnasium.make_vec(..., "
                  "vectorization_mode='vector_entry_point', actions='targets'), any num_envs")
        if render_mode not in (None, "rgb_array", "human"):
            _fail("render_mode", render_mode, "None, 'rgb_array' or 'human'")
        if render_mode == "human" and not _has_display():
            _fail("render_mode", render_mode, "'human' needs a display (DISPLAY/WAYLAND_DISPLAY is not set): use "
                  "'rgb_array' and show or record the frames")
        self.params = gym_parameters(
            task=task, speed=speed, radius=radius, turn_direction=turn_direction,
            max_decisions=max_decisions, reward=reward, compile=compile,
        )
        self.render_mode = render_mode
        # A one-row TorchRL env: its seeded generator draws the starts and the irregular redraws (same seeds,
        # same episodes) and it builds scenario resets.
        self.env = GuidanceEnv(dataclasses.replace(self.params, compile=False), num_envs=1, device="cpu", seed=None)
        self.action_space = spaces.Discrete(NUM_ACTIONS)
        low, high = observation_bounds(self.params)
        self.observation_space = spaces.Box(low, high, dtype=np.float32)
        self.maneuver_names = MANEUVER_NAMES
        self._irregular = self.params.destination.name is MotionKind.IRREGULAR
        # The destination's start and (but for irregular motion) its speed and turn rate, rounded to float32
        # as GuidanceEnv holds them.
        self._start = tuple(torch.tensor(self.params.destination.start).tolist())
        self._start_motion = (0.0, 0.0)
        if not self._irregular:  # (irregular motion draws, from the global generator without one)
            speed, turn_rate = self.params.destination.initial_motion(1, None, "cpu")
            self._start_motion = (float(speed[0]), float(turn_rate[0]))
        self._running = False  # False before reset and after the end of an episode
        self._aircraft_path: list = []  # positions at each decision, kept only when rendering
        self._destination_path: list = []
        self._window = None  # the "human" mode's matplotlib figure and image

    # ------------------------------------------------------------------ helpers
    def _observation(self) -> np.ndarray:
        simulation = self.params.simulation
        row = observation_row(self._aircraft, self._destination, self._last_action, simulation.airspace,
                              simulation.limits)
        return np.array(row, dtype=np.float32)

    def _info(self) -> dict[str, Any]:
        return {
            "outcome": _OUTCOME_NAMES[self._outcome],
            "aircraft_state": np.array(self._aircraft),
            "destination_state": np.array(self._destination),
            "step_count": self._step_count,
            "instruction_count": self._instruction_count,
            "episode_return": self._episode_return,
        }

    def _potential(self, terminal: bool) -> float:
        return potential_row(self._aircraft, self._destination, self._last_action, self._action_before_last,
                             terminal, self.params.reward)

    # ------------------------------------------------------------------ gymnasium API
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        seed = checked_seed(seed)
        super().reset(seed=seed)
        if seed is not None:
            self.env.set_seed(seed)
        with torch.no_grad():
            scenario = scenario_reset(self.env, options)
        if scenario is not None:
            state = scenario["scenario"]
            self._aircraft = tuple(state["aircraft_state"][0].tolist())
            self._destination = tuple(state["destination_state"][0].tolist())
            self._destination_speed = float(state["destination_speed"][0])
            self._destination_turn_rate = float(state["destination_turn_rate"][0])
        else:  # GuidanceEnv._reset's draws, in its order, in floats (its one-row torch form cost a decision)
            speed, turn_rate = self._start_motion
            if self._irregular:  # drawn from the generator
                speed, turn_rate = self.params.destination.initial_motion(1, self.env.generator, self.env.device)
                speed, turn_rate = float(speed[0]), float(turn_rate[0])
            self._destination, self._destination_speed, self._destination_turn_rate = self._start, speed, turn_rate
            self._aircraft = initial_aircraft_row(self.params.initial_state, self._start, self.env.generator)
        self._last_action = self._action_before_last = 0  # steady flight, as GuidanceEnv
        self._step_count = self._instruction_count = 0
        self._episode_return = 0.0
        self._outcome = int(Outcome.RUNNING)
        self._running = True
        self._potential_now = self._potential(False)  # the next step's potential before (Phi of equation 8)
        if self.render_mode is not None:
            self._aircraft_path, self._destination_path = [self._aircraft], [self._destination]
            if self.render_mode == "human":
                self.render()
        return self._observation(), self._info()

    def step(self, action):
        if not self._running:
            raise RuntimeError("agrl/Guidance-v0: call reset() before step() (and after an episode ends)")
        if not (isinstance(action, (int, np.integer)) and 0 <= action < NUM_ACTIONS):
            try:
                if isinstance(action, (str, bytes)):  # "2" is a name, not a maneuver index
                    raise TypeError
                index = int(action)
                integral = float(action) == index  # 2.0 is maneuver 2; 2.5 is no maneuver
            except (TypeError, ValueError, OverflowError):
                index, integral = None, False
            if not integral or not self.action_space.contains(index):
                _fail("action", action, f"an integer maneuver index in [0, {NUM_ACTIONS - 1}]")
            action = index
        action = int(action)
        if self._irregular:  # GuidanceEnv's step's redraw, from the same generator
            speed, turn_rate = self.env.next_destination_motion(
                torch.tensor([self._destination_speed]), torch.tensor([self._destination_turn_rate]))
            self._destination_speed, self._destination_turn_rate = float(speed[0]), float(turn_rate[0])
        potential_before = self._potential_now  # the state has not changed since it was computed
        result = reference_decision(self._aircraft, self._destination, self._destination_speed,
                                    self._destination_turn_rate, action, self.params.simulation,
                                    self.params.maneuvers)
        self._step_count += 1
        outcome = result.outcome
        if outcome == Outcome.RUNNING and self._step_count >= self.params.max_decisions:
            outcome = int(Outcome.BUDGET_EXHAUSTED)
        terminated = outcome != Outcome.RUNNING
        # An instruction is a decision that changes the maneuver being flown (and pays the switch cost).
        switched = action != self._last_action
        self._instruction_count += int(switched)
        self._aircraft, self._destination, self._outcome = result.aircraft_state, result.destination_state, outcome
        self._action_before_last, self._last_action = self._last_action, action
        self._potential_now = self._potential(terminated)
        reward = step_reward_row(outcome, potential_before, self._potential_now, self.params.reward, switched)
        self._episode_return += reward
        self._running = not terminated
        if self.render_mode is not None:
            self._aircraft_path.append(self._aircraft)
            self._destination_path.append(self._destination)
            if self.render_mode == "human":
                self.render()
        return self._observation(), reward, terminated, False, self._info()

    def render(self):
        """The episode so far as an ``(H, W, 3)`` uint8 frame ("rgb_array"), or shown in a window ("human")."""
        if self.render_mode is None:
            return None
        if not self._aircraft_path:
            raise RuntimeError("agrl/Guidance-v0: call reset() before render()")
        from agrl.plots import episode_frame

        title = f"{self.params.destination.name.value}  decision {self._step_count}/{self.params.max_decisions}"
        frame = episode_frame(self._aircraft_path, self._destination_path, Outcome(self._outcome),
                              self.params.simulation.airspace, f"{title}  return {self._episode_return:.2f}")
        if self.render_mode == "rgb_array":
            return frame
        self._show(frame)
        return None

    def _show(self, frame: np.ndarray) -> None:
        import matplotlib.pyplot as plt

        if self._window is None:
            _use_interactive_matplotlib()
            figure = plt.figure(figsize=(frame.shape[1] / 100, frame.shape[0] / 100), dpi=100)
            axes = figure.add_axes((0, 0, 1, 1))
            axes.set_axis_off()
            self._window = (figure, axes.imshow(frame))
            plt.show(block=False)
        else:
            self._window[1].set_data(frame)
        plt.pause(1.0 / self.metadata["render_fps"])

    def close(self):
        self._running = False
        if self._window is not None:
            import matplotlib.pyplot as plt

            plt.close(self._window[0])
            self._window = None


def _use_interactive_matplotlib() -> None:
    """Switch matplotlib (which agrl.plots sets to the file-only Agg) to the first interactive backend that loads."""
    import matplotlib.pyplot as plt

    for backend in ("macosx", "qtagg", "gtk4agg", "gtk3agg", "tkagg", "wxagg"):
        try:
            plt.switch_backend(backend)
            return
        except (ImportError, RuntimeError, ValueError):
            continue
    raise RuntimeError("render_mode='human': no interactive matplotlib backend (Qt, GTK, Tk, wx) could be loaded; "
                       "use render_mode='rgb_array'")
