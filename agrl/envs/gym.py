"""A single, unbatched gymnasium environment over :class:`agrl.envs.GuidanceEnv`.

``import agrl`` registers it as ``agrl/Guidance-v0``, so any library that trains on
gymnasium environments can use the paper's MDP::

    import gymnasium, agrl
    env = gymnasium.make("agrl/Guidance-v0", task="uniform", speed=50.0)
    obs, info = env.reset(seed=0)
    obs, reward, terminated, truncated, info = env.step(env.action_space.sample())

It is a thin layer: one row of a ``GuidanceEnv`` (``num_envs=1``, CPU) does the
simulation, the reward and the observation (``GuidanceEnv.observe``), so the
gymnasium and TorchRL environments cannot drift apart. The task parameters are
built from the same schema and defaults as ``python -m agrl.train``
(:mod:`agrl.config`): ``conf/simulation/paper.yaml`` and ``conf/reward/*.yaml``
equal the dataclass defaults, and the per-task destination defaults below are
those of ``conf/task/*.yaml`` (a test composes ``conf/`` and compares).

Episodes end with ``terminated=True`` on success, on leaving the airspace and
when the decision budget is spent: the budget is part of the paper's MDP (it pays
``c3``), not a time limit, so ``truncated`` is always False.
"""

from __future__ import annotations

import math
from typing import Any

import gymnasium
import numpy as np
import torch
from gymnasium import spaces

from agrl.config import RewardConfig, SimulationConfig, TaskConfig, to_guidance_parameters
from agrl.core.aircraft import MANEUVER_NAMES
from agrl.core.observation import OBSERVATION_FEATURES, OBSERVATION_SIZE
from agrl.core.parameters import GuidanceParameters, MotionKind
from agrl.core.termination import Outcome
from agrl.envs.guidance import NUM_ACTIONS, GuidanceEnv

ENV_ID = "agrl/Guidance-v0"

TASKS = tuple(kind.value for kind in MotionKind)
REWARDS = ("none", "continuous", "position", "both")  # Table 3's four rows, as conf/reward/*.yaml
#: Destination defaults of conf/task/*.yaml (``speed``/``radius`` are null at the root there).
TASK_DEFAULTS: dict[str, dict[str, float]] = {
    "fixed": {},
    "uniform": {"speed": 50.0},
    "curved": {"speed": 20.0, "radius": 1_000.0, "turn_direction": 1},
    "irregular": {},
}


def _fail(name: str, value: Any, allowed: str) -> None:
    raise ValueError(f"{name}={value!r} is not allowed: {allowed}")


def _finite_positive(name: str, value: Any, task: str, what: str) -> float:
    try:
        number = float(value)
    except (TypeError, ValueError):
        number = math.nan
    if isinstance(value, bool) or not (math.isfinite(number) and number > 0):
        _fail(name, value, f"task={task} needs a finite {what} > 0")
    return number


def guidance_parameters(
    task: str = "fixed",
    speed: float | None = None,
    radius: float | None = None,
    turn_direction: int | None = None,
    max_decisions: int | None = None,
    reward: str = "both",
    compile: bool = False,
) -> GuidanceParameters:
    """The :class:`GuidanceParameters` that ``python -m agrl.train task=... reward=...`` would use.

    Raises ``ValueError`` (one line) naming a bad value and what is allowed.
    """
    if task not in TASKS:
        _fail("task", task, f"one of {', '.join(TASKS)}")
    if reward not in REWARDS:
        _fail("reward", reward, f"one of {', '.join(REWARDS)}")
    if not isinstance(compile, bool):
        _fail("compile", compile, "True or False")
    defaults = TASK_DEFAULTS[task]
    given = {"speed": speed, "radius": radius, "turn_direction": turn_direction}
    for name, value in given.items():
        if value is not None and name not in defaults:
            users = [t for t, d in TASK_DEFAULTS.items() if name in d]
            _fail(name, value, f"task={task} has no destination {name} (only task={' or '.join(users)})")
    values: dict[str, Any] = {}
    if "speed" in defaults:
        values["speed"] = _finite_positive(
            "speed", defaults["speed"] if speed is None else speed, task, "destination speed in m/s"
        )
    if "radius" in defaults:
        values["radius"] = _finite_positive(
            "radius", defaults["radius"] if radius is None else radius, task, "turning radius in m"
        )
    if "turn_direction" in defaults:
        direction = defaults["turn_direction"] if turn_direction is None else turn_direction
        if isinstance(direction, bool) or direction not in (-1, 1):
            _fail("turn_direction", turn_direction, "+1 (counter-clockwise) or -1 (clockwise)")
        values["turn_direction"] = int(direction)
    task_config = TaskConfig(name=task, **values)  # the schema's own checks run here, as under Hydra

    budget: dict[str, int] = {}
    if max_decisions is not None:
        integral = isinstance(max_decisions, (int, np.integer)) and not isinstance(max_decisions, bool)
        if not integral or max_decisions < 1:
            _fail("max_decisions", max_decisions, "an integer >= 1 (decisions of 3 s per episode)")
        budget["max_decisions"] = int(max_decisions)
    simulation = SimulationConfig(compile=compile, **budget)

    # conf/reward/{none,continuous,position}.yaml inherit reward/both and switch the two shaping terms.
    reward_config = RewardConfig(
        name=reward,
        use_continuous_action=reward in ("continuous", "both"),
        use_position=reward in ("position", "both"),
    )
    return to_guidance_parameters(task_config, reward_config, simulation, compile=compile)


def observation_bounds(params: GuidanceParameters) -> tuple[np.ndarray, np.ndarray]:
    """Finite bounds of :func:`agrl.core.observation.policy_observation` for ``params``.

    Every feature is a sine/cosine, a clamped quantity or a position inside the
    airspace mapped to [-1, 1]; an aircraft is at most one integration step
    outside the airspace when its episode ends, hence the small margin.
    """
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
    low = np.empty(OBSERVATION_SIZE, dtype=np.float32)
    high = np.empty(OBSERVATION_SIZE, dtype=np.float32)
    for index, name in enumerate(OBSERVATION_FEATURES):
        if name.startswith("last_action_"):
            low[index], high[index] = 0.0, 1.0
        else:
            low[index], high[index] = bounds.get(name, (-1.0 - margin, 1.0 + margin))
    return low, high


class GuidanceGymEnv(gymnasium.Env):
    """The paper's guidance MDP as an unbatched ``gymnasium.Env`` (``Discrete(7)`` maneuvers).

    Keyword arguments (as ``gymnasium.make("agrl/Guidance-v0", **kwargs)``):

    - ``task``: ``fixed`` (default), ``uniform``, ``curved`` or ``irregular``;
    - ``speed`` (m/s; uniform default 50, curved 20), ``radius`` (m; curved, default 1000),
      ``turn_direction`` (curved: +1 counter-clockwise, -1 clockwise);
    - ``max_decisions``: the decision budget (default 200, ``conf/simulation/paper.yaml``);
    - ``reward``: ``none``, ``continuous``, ``position`` or ``both`` (default; Table 3);
    - ``compile``: fuse the 20 ms step with ``torch.compile`` (default False: compiling costs
      10-20 s of start-up, which a single environment rarely wins back).

    Seed with ``reset(seed=...)``. ``info`` holds ``outcome`` (``running``, ``success``,
    ``out_of_airspace``, ``budget_exhausted``), ``aircraft_state`` (x, y, z, v, theta, psi, phi),
    ``destination_state`` (x, y, z, psi), ``step_count``, ``instruction_count`` and
    ``episode_return``.
    """

    metadata = {"render_modes": []}

    def __init__(
        self,
        task: str = "fixed",
        speed: float | None = None,
        radius: float | None = None,
        turn_direction: int | None = None,
        max_decisions: int | None = None,
        reward: str = "both",
        compile: bool = False,
        render_mode: str | None = None,
    ):
        if render_mode is not None:
            _fail("render_mode", render_mode, "None (this environment does not render)")
        self.params = guidance_parameters(
            task=task, speed=speed, radius=radius, turn_direction=turn_direction,
            max_decisions=max_decisions, reward=reward, compile=compile,
        )
        self.render_mode = render_mode
        self.env = GuidanceEnv(self.params, num_envs=1, device="cpu", seed=None)
        self.action_space = spaces.Discrete(NUM_ACTIONS)
        low, high = observation_bounds(self.params)
        self.observation_space = spaces.Box(low, high, dtype=np.float32)
        self.maneuver_names = MANEUVER_NAMES
        self._state = None  # the TorchRL row being simulated; None before reset and after the end

    # ------------------------------------------------------------------ helpers
    def _observation(self, state) -> np.ndarray:
        return state["observation"][0].numpy().astype(np.float32, copy=True)

    def _info(self, state) -> dict[str, Any]:
        return {
            "outcome": Outcome(int(state["outcome"][0])).name.lower(),
            "aircraft_state": state["aircraft_state"][0].numpy().copy(),
            "destination_state": state["destination_state"][0].numpy().copy(),
            "step_count": int(state["step_count"][0]),
            "instruction_count": int(state["instruction_count"][0]),
            "episode_return": float(state["episode_return"][0]),
        }

    # ------------------------------------------------------------------ gymnasium API
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        if seed is not None:
            self.env.set_seed(int(seed))
        with torch.no_grad():
            self._state = self.env.reset()
        return self._observation(self._state), self._info(self._state)

    def step(self, action):
        if self._state is None:
            raise RuntimeError("agrl/Guidance-v0: call reset() before step() (and after an episode ends)")
        if not self.action_space.contains(action):
            try:
                action = int(action)
            except (TypeError, ValueError):
                action = -1
            if not self.action_space.contains(action):
                _fail("action", action, f"an integer maneuver index in [0, {NUM_ACTIONS - 1}]")
        state = self._state.clone(False)
        state["action"] = torch.tensor([int(action)], dtype=torch.int64)
        with torch.no_grad():
            following = self.env.step(state)["next"]
        terminated = bool(following["terminated"][0, 0])
        observation, info = self._observation(following), self._info(following)
        reward = float(following["reward"][0, 0])
        self._state = None if terminated else following
        return observation, reward, terminated, False, info

    def close(self):
        self._state = None
