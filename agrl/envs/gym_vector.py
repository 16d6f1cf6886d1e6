"""The guidance MDP as a gymnasium vector env on the batched torch simulator (numpy in and out).

::

    import gymnasium, agrl
    envs = gymnasium.make_vec("agrl/Guidance-v0", num_envs=4096, vectorization_mode="vector_entry_point",
                              task="uniform")    # compiled (from 256 rows; docs/using_an_agent.md)
    observations, infos = envs.reset(seed=0)                 # (4096, 23) float32
    observations, rewards, terminated, truncated, infos = envs.step(envs.action_space.sample())

All rows are one :class:`agrl.envs.GuidanceEnv` (``num_envs`` rows), so a step costs one batched
decision instead of ``num_envs`` Python ones. Autoreset follows gymnasium 1.x's default,
``AutoresetMode.NEXT_STEP``: the step on which a row's episode ends returns its terminal
observation with ``terminated=True``; the next step ignores that row's action and returns its
reset observation with reward 0 and ``terminated=truncated=False``. ``autoreset_mode="SameStep"``
(``AutoresetMode.SAME_STEP``, what stable-baselines3 expects) resets such rows within the step that
ends them: that step returns the reset observation, and the terminal observation and info in
``info["final_obs"]`` (an object array, ``None`` for other rows) and ``info["final_info"]``.

Seeding: ``reset(seed=s)`` seeds the batched generator (one seed for all rows; a list of
per-row seeds is refused). With ``num_envs=1`` the draws are those of the single env
(:mod:`agrl.envs.gym`) from the same seed, so both fly the same episodes, resets included.
``reset(options=...)`` takes the single env's scenario keys with one row per env
(``aircraft_state`` ``(num_envs, 7)``, ...).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch
from gymnasium import spaces
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from agrl.core.termination import Outcome
from agrl.envs.guidance import HELD_TARGETS_KEY, SCENARIO_KEYS, GuidanceEnv
from agrl.envs.gym import _fail, checked_seed, gym_parameters, observation_bounds, scenario_reset

#: Entries of the TorchRL state that make a row's state (what a reset replaces).
_ROW_KEYS = (*SCENARIO_KEYS, "last_action", "action_before_last", "step_count", "episode_return",
             "instruction_count", "outcome", "observation")
_OUTCOME_NAMES = np.array([outcome.name.lower() for outcome in Outcome])


#: Rows from which the vector env compiles its step by default: below, the eager step's per-call cost is small
#: beside a first compilation's half minute.
COMPILED_FROM_ROWS = 256


class GuidanceVectorEnv(VectorEnv):
    """``num_envs`` guidance rows stepped together; the single env's keyword arguments plus ``device``.

    ``compile=True`` fuses the 20 ms step with ``torch.compile``: several times faster from a few hundred rows
    on, after one compilation of 20-30 s that later processes load from the user's compile cache in about a
    second (:func:`agrl.core.compiled.compile_cache_dir`). The default, ``None``, compiles from
    :data:`COMPILED_FROM_ROWS` rows on. ``info`` has the single env's keys, one entry per
    row (``outcome`` as strings, ``aircraft_state`` ``(num_envs, 7)``, ...), each with gymnasium's
    ``_key`` mask.
    """

    metadata = {"render_modes": [], "autoreset_mode": AutoresetMode.NEXT_STEP}
    AUTORESET_MODES = (AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP)

    def __init__(
        self,
        num_envs: int = 1,
        task: str = "fixed",
        speed: float | None = None,
        radius: float | None = None,
        turn_direction: int | None = None,
        max_decisions: int | None = None,
        reward: str | None = None,
        compile: bool | None = None,
        device: str = "cpu",
        actions: str | None = None,
        render_mode: str | None = None,
        autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
    ):
        if isinstance(num_envs, bool) or not isinstance(num_envs, (int, np.integer)) or num_envs < 1:
            _fail("num_envs", num_envs, "an integer >= 1")
        if render_mode is not None:
            _fail("render_mode", render_mode, "None (this vector environment does not render)")
        modes = {mode.value: mode for mode in self.AUTORESET_MODES}
        if modes.get(getattr(autoreset_mode, "value", autoreset_mode)) is None:
            _fail("autoreset_mode", autoreset_mode, f"one of {', '.join(modes)}")
        self.metadata = {**self.metadata, "autoreset_mode": modes[getattr(autoreset_mode, "value", autoreset_mode)]}
        if compile is None:
            compile = int(num_envs) >= COMPILED_FROM_ROWS
        elif not isinstance(compile, bool):
            _fail("compile", compile, f"True, False or None (compiled from {COMPILED_FROM_ROWS} rows)")
        self.params = gym_parameters(
            task=task, speed=speed, radius=radius, turn_direction=turn_direction,
            max_decisions=max_decisions, reward=reward, compile=compile, actions=actions,
        )
        self.num_envs = int(num_envs)
        self.render_mode = render_mode
        self.env = GuidanceEnv(self.params, num_envs=self.num_envs, device=device, seed=None)
        self.single_action_space = spaces.Discrete(self.env.num_actions)
        self._row_keys = (*_ROW_KEYS, HELD_TARGETS_KEY) if self.env.holds_targets else _ROW_KEYS
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        low, high = observation_bounds(self.params)
        self.single_observation_space = spaces.Box(low, high, dtype=np.float32)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self._state = None  # the TorchRL rows; None before reset
        self._autoreset = np.zeros(self.num_envs, dtype=bool)
        self._all_rows = np.ones(self.num_envs, dtype=bool)

    # ------------------------------------------------------------------ helpers
    def _outputs(self, state) -> tuple[np.ndarray, dict[str, Any]]:
        observation = state["observation"].cpu().numpy().copy()
        info = {
            "outcome": _OUTCOME_NAMES[state["outcome"].cpu().numpy()],
            "aircraft_state": state["aircraft_state"].cpu().numpy().copy(),
            "destination_state": state["destination_state"].cpu().numpy().copy(),
            "step_count": state["step_count"].cpu().numpy().copy(),
            "instruction_count": state["instruction_count"].cpu().numpy().copy(),
            "episode_return": state["episode_return"].cpu().numpy().copy(),
        }
        if self.env.holds_targets:
            info[HELD_TARGETS_KEY] = state[HELD_TARGETS_KEY].cpu().numpy().copy()
        for key in list(info):
            info[f"_{key}"] = self._all_rows
        return observation, info

    def _restart(self, state, rows: torch.Tensor):
        """``state`` with the ``rows`` (a bool mask) replaced by fresh starts: the next draws of the generator,
        one per restarting row in row order (with ``num_envs=1``, the single env's draws).

        Only the restarting rows are drawn and observed (``GuidanceEnv.fresh_rows``), not a whole batch. The
        entries are replaced, not written into: a step's outputs share tensors with its inputs (the caller's
        action array among them)."""
        index = rows.nonzero().squeeze(-1)
        fresh = self.env.fresh_rows(index.numel())
        for key in self._row_keys:
            state[key] = state[key].index_put((index,), fresh[key])
        return state

    def _actions(self, actions) -> torch.Tensor:
        try:
            array = np.asarray(actions)
        except ValueError:  # ragged nesting
            _fail("actions", actions, f"{self.num_envs} integer action indices in [0, {self.env.num_actions - 1}]")
        valid = (array.shape == (self.num_envs,) and np.issubdtype(array.dtype, np.integer)
                 and bool(((array >= 0) & (array < self.env.num_actions)).all()))
        if not valid:
            shown = actions if array.size <= 8 else f"array of shape {array.shape}, dtype {array.dtype}"
            if array.size > 8 and array.shape == (self.num_envs,) and np.issubdtype(array.dtype, np.integer):
                # a long batch: its first bad row
                bad = int(np.flatnonzero((array < 0) | (array >= self.env.num_actions))[0])
                shown = f"{shown} with actions[{bad}]={array[bad]}"
            _fail("actions", shown, f"{self.num_envs} integer action indices in [0, {self.env.num_actions - 1}]")
        return torch.as_tensor(array, dtype=torch.int64, device=self.env.device)

    # ------------------------------------------------------------------ gymnasium API
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        seed = checked_seed(seed, "None or one integer in [0, 2**64 - 1] (one batched generator drives every row)")
        super().reset(seed=seed)
        if seed is not None:
            self.env.set_seed(seed)
        with torch.no_grad():
            scenario = scenario_reset(self.env, options)
            self._state = self.env.reset(scenario) if scenario is not None else self.env.reset()
        self._autoreset[:] = False
        return self._outputs(self._state)

    def step(self, actions):
        if self._state is None:
            raise RuntimeError("agrl/Guidance-v0 vector env: call reset() before step()")
        action = self._actions(actions)
        resetting = self._autoreset
        with torch.no_grad():
            if resetting.all():
                following = self.env.reset()
                reward = torch.zeros(self.num_envs, device=self.env.device)
                terminated = torch.zeros(self.num_envs, dtype=torch.bool, device=self.env.device)
            else:
                carrier = self._state.select(*self._row_keys)
                carrier["action"] = action
                following = self.env.step(carrier)["next"]
                reward, terminated = following["reward"][..., 0], following["terminated"][..., 0]
                if resetting.any():  # gymnasium's next-step autoreset: these rows restart, their action ignored
                    mask = torch.as_tensor(resetting, device=self.env.device)
                    following = self._restart(following, mask)
                    reward = torch.where(mask, 0.0, reward)
                    terminated = terminated & ~mask
            final = None
            if self.metadata["autoreset_mode"] is AutoresetMode.SAME_STEP and bool(terminated.any()):
                final = self._outputs(following)  # the terminal rows, before they restart
                following = self._restart(following, terminated)
        self._state = following
        terminated = terminated.cpu().numpy().copy()
        observation, info = self._outputs(following)
        if self.metadata["autoreset_mode"] is AutoresetMode.NEXT_STEP:
            self._autoreset = terminated.copy()
        elif final is not None:
            final_obs = np.full(self.num_envs, None, dtype=object)
            for row in np.flatnonzero(terminated):
                final_obs[row] = final[0][row]
            info.update(final_obs=final_obs, _final_obs=terminated, final_info=final[1], _final_info=terminated)
        truncated = np.zeros(self.num_envs, dtype=bool)  # the decision budget is part of the MDP (c3)
        return observation, reward.cpu().numpy().astype(np.float64), terminated, truncated, info

    def close_extras(self, **kwargs):
        self._state = None
