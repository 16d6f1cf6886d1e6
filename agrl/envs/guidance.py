"""The batched TorchRL guidance environment.

State lives in the TensorDict (the paper's equation-4 fields plus the
destination's motion and two counters), so the environment itself holds only
its parameters and a random generator: partial resets, scenario replay and
re-simulation by the policy-reuse step all follow from that.
"""

from __future__ import annotations

import dataclasses

import torch
from tensordict import TensorDict, TensorDictBase
from torchrl.data import Bounded, Categorical, Composite, Unbounded
from torchrl.envs import EnvBase

from agrl.config.records import saved_agent_config, saved_guidance_parameters
from agrl.config.task import TaskConfig, require_max_decisions
from agrl.core.aircraft import AIRCRAFT_FIELDS, MANEUVER_NAMES
from agrl.core.autopilot import HeldTargets, apply_target_action
from agrl.core.compiled import padded_rows
from agrl.core.destinations import redraw_irregular_motion
from agrl.core.initial_states import sample_initial_aircraft
from agrl.core.observation import observation_function, observation_size, target_observation_function
from agrl.core.parameters import GuidanceParameters, MotionKind
from agrl.core.reward import REWARD_PART_KEYS, step_reward
from agrl.core.simulation import DecisionResult, DecisionSimulator
from agrl.core.termination import Outcome, decision_outcome
from agrl.envs.partial_reset import ZERO_AT_START, put_rows

#: The paper's maneuvers (``actions=maneuvers``); an env's own count: ``GuidanceEnv.num_actions``.
NUM_ACTIONS = len(MANEUVER_NAMES)

#: Entries that together are the full simulator state of one row (a maneuver agent's; an agent holding targets
#: adds :data:`HELD_TARGETS_KEY`: ``GuidanceEnv.row_keys``).
STATE_KEYS = (
    "aircraft_state",
    "destination_state",
    "destination_speed",
    "destination_turn_rate",
    "last_action",
    "action_before_last",
    "step_count",
    "episode_return",
    "instruction_count",
)
#: Entries a scenario (explicit initial conditions) provides; see :meth:`GuidanceEnv.scenario`.
SCENARIO_KEYS = ("aircraft_state", "destination_state", "destination_speed", "destination_turn_rate")
#: The targets an agent with ``actions=targets`` holds, ``(..., 3)``: heading rad, altitude m, speed m/s.
HELD_TARGETS_KEY = "held_targets"
#: Where the held targets' fields are in ``aircraft_state`` (an episode starts holding what the aircraft flies).
_HELD_FIELDS = [AIRCRAFT_FIELDS.index(name) for name in ("heading", "z", "speed")]


class GuidanceEnv(EnvBase):
    """Aircraft guidance to a fixed or moving destination (the paper's MDP), batched.

    Each step is one 3 s decision made of 150 integration steps of 20 ms. Actions are the seven maneuvers
    (``Categorical(7)``), or with ``params.actions`` holding targets, target-holding actions
    (``Categorical(num_actions)``, :func:`agrl.core.autopilot.target_action_table`) that an autopilot flies; the
    held targets are then the state's ``held_targets``, and an instruction is an action that changes one. The
    reward is equation 5 plus the optional switch cost (:func:`agrl.core.reward.step_reward`, with its parts as
    entries, :data:`REWARD_PART_KEYS`).

    Scenario replay: ``env.reset(env.scenario(aircraft_state=..., destination_state=...,
    destination_speed=..., destination_turn_rate=...))`` starts the (masked) rows from
    those initial conditions instead of sampling them.

    ``observation`` picks the policy input (``agent.observation``): ``relative`` (this project's default,
    :func:`agrl.core.observation.policy_observation`) or ``absolute`` (equation 4 as it stands,
    :func:`agrl.core.observation.absolute_observation`).
    """

    batch_locked = True

    def __init__(
        self,
        params: GuidanceParameters,
        num_envs: int = 1,
        device: torch.device | str = "cpu",
        seed: int | None = None,
        observation: str = "relative",
    ):
        if isinstance(num_envs, bool) or not hasattr(num_envs, "__index__") or num_envs < 1:
            raise ValueError(f"num_envs={num_envs!r} is not allowed: an integer >= 1")
        try:
            device = torch.device(device)
        except (RuntimeError, TypeError):
            raise ValueError(f"device={device!r} is not allowed: a torch device, e.g. cpu or cuda") from None
        super().__init__(device=device, batch_size=torch.Size([int(num_envs)]))
        self.params = params
        self.observation_kind = observation
        require_max_decisions(self.params.max_decisions)  # the schema's check: a record may be built without it
        actions = self.params.actions
        self.holds_targets = actions.holds_targets
        self.num_actions = self.params.num_actions
        self.row_keys = (*STATE_KEYS, HELD_TARGETS_KEY) if self.holds_targets else STATE_KEYS
        self._observation_size = observation_size(observation, self.holds_targets)  # one line on an unknown kind
        self._observation = (target_observation_function(observation) if self.holds_targets
                             else observation_function(observation))
        self.target_table = None
        if self.holds_targets:
            simulation = self.params.simulation
            table = actions.target_table(simulation.airspace, simulation.limits)
            self.target_table = type(table)(*(field.to(self.device) for field in table))
        self.simulator = DecisionSimulator(
            self.params.simulation, self.params.maneuvers.controls(self.device), compile=self.params.compile,
            autopilot=actions.autopilot(self.params.maneuvers),
        )
        self._destination_start = torch.tensor(self.params.destination.start, device=self.device)
        self._generator = torch.Generator(device=self.device)
        self._pending_state: TensorDictBase | None = None
        self._make_specs()
        self._set_seed(seed if seed is not None else int(torch.empty((), dtype=torch.int64).random_()))

    @classmethod
    def for_saved_agent(cls, saved: dict, num_envs: int = 1, *, task: TaskConfig | None = None,
                        device: torch.device | str = "cpu", seed: int | None = None,
                        compile: bool | None = None) -> GuidanceEnv:
        """The env a checkpoint's agent acts in, from the checkpoint's saved config (``saved``): its task (or
        ``task`` instead), reward, simulation, action set and observation; ``compile`` overrides the saved
        simulation's choice when given."""
        return cls(saved_guidance_parameters(saved, task, compile=compile), num_envs=num_envs, device=device,
                   seed=seed, observation=saved_agent_config(saved).observation)

    # ------------------------------------------------------------------ specs
    def _make_specs(self) -> None:
        batch = self.batch_size
        self.observation_spec = Composite(
            observation=Unbounded((*batch, self._observation_size), device=self.device),
            aircraft_state=Unbounded((*batch, 7), device=self.device),
            destination_state=Unbounded((*batch, 4), device=self.device),
            destination_speed=Bounded(0.0, torch.inf, batch, device=self.device),
            destination_turn_rate=Unbounded(batch, device=self.device),
            last_action=Categorical(self.num_actions, batch, device=self.device),
            action_before_last=Categorical(self.num_actions, batch, device=self.device),
            step_count=Bounded(0, self.params.max_decisions, batch, dtype=torch.int64, device=self.device),
            # bookkeeping for statistics, not policy inputs:
            episode_return=Unbounded(batch, device=self.device),
            instruction_count=Bounded(0, self.params.max_decisions, batch, dtype=torch.int64, device=self.device),
            outcome=Categorical(len(Outcome), batch, device=self.device),
            **{key: Unbounded(batch, device=self.device) for key in REWARD_PART_KEYS},
            shape=batch,
            device=self.device,
        )
        if self.holds_targets:
            self.observation_spec[HELD_TARGETS_KEY] = Unbounded((*batch, 3), device=self.device)
        self.action_spec = Categorical(self.num_actions, batch, device=self.device)
        self.reward_spec = Unbounded((*batch, 1), device=self.device)
        self.done_spec = Composite(
            done=Categorical(2, (*batch, 1), dtype=torch.bool, device=self.device),
            terminated=Categorical(2, (*batch, 1), dtype=torch.bool, device=self.device),
            shape=batch,
            device=self.device,
        )

    def _set_seed(self, seed: int | None) -> None:
        self._generator.manual_seed(int(seed) if seed is not None else 0)

    @property
    def generator(self) -> torch.Generator:
        """The env's own random stream: initial states and the irregular destination's redraws."""
        return self._generator

    def generator_state(self) -> torch.Tensor:
        """The state of the env's own random stream (initial states, irregular motion), for exact resume."""
        return self._generator.get_state()

    def set_generator_state(self, state: torch.Tensor) -> None:
        self._generator.set_state(state)

    # ------------------------------------------------------------------ helpers
    def observe(self, state: TensorDictBase) -> torch.Tensor:
        """The policy input from the raw fields (one function for env and reuse step)."""
        simulation = self.params.simulation
        return self._observation(
            state["aircraft_state"], state["destination_state"],
            state[HELD_TARGETS_KEY] if self.holds_targets else state["last_action"],
            simulation.airspace, simulation.limits,
        )

    def targets_after(self, state: TensorDictBase) -> tuple[torch.Tensor, torch.Tensor]:
        """For an agent holding targets: the targets held after ``state``'s ``action`` ``(..., 3)``, and whether
        that action is an instruction (it changed a target)."""
        held = HeldTargets(*state[HELD_TARGETS_KEY].unbind(-1))
        targets, changed = apply_target_action(held, state["action"].long(), self.target_table)
        return torch.stack(tuple(targets), dim=-1), changed

    def scenario(
        self,
        aircraft_state: torch.Tensor,
        destination_state: torch.Tensor | None = None,
        destination_speed: torch.Tensor | float | None = None,
        destination_turn_rate: torch.Tensor | float | None = None,
    ) -> TensorDict:
        """A reset TensorDict that starts every row from explicit initial conditions.

        Missing destination fields default to the task's start and motion.
        """
        batch = self.batch_size
        count = batch.numel()
        speed, turn_rate = self.params.destination.initial_motion(count, self._generator, self.device)
        aircraft_state = torch.as_tensor(aircraft_state, dtype=torch.float32, device=self.device).expand(*batch, 7)
        if destination_state is None:
            destination_state = self._destination_start
        destination_state = torch.as_tensor(destination_state, dtype=torch.float32, device=self.device)
        values = {
            "aircraft_state": aircraft_state,
            "destination_state": destination_state.expand(*batch, 4),
            "destination_speed": speed if destination_speed is None else destination_speed,
            "destination_turn_rate": turn_rate if destination_turn_rate is None else destination_turn_rate,
        }
        values = {
            key: torch.as_tensor(value, dtype=torch.float32, device=self.device).expand(
                *batch, *((7,) if key == "aircraft_state" else (4,) if key == "destination_state" else ())
            ).clone()
            for key, value in values.items()
        }
        return TensorDict({"scenario": TensorDict(values, batch_size=batch)}, batch_size=batch, device=self.device)

    def set_initial_state_distribution(self, distribution) -> None:
        """Change where new episodes start (used by the training curriculum)."""
        self.params = dataclasses.replace(self.params, initial_state=distribution)

    def set_switch_cost(self, switch_cost: float) -> None:
        """Price each instruction from the next step on at ``switch_cost`` reward units (a run's ``finetune``)."""
        self.params = self.params.with_switch_cost(switch_cost)

    def restore_on_next_reset(self, state: TensorDictBase) -> None:
        """Make the next full reset return ``state`` (a saved batch of mid-episode rows).

        Used to resume training exactly: a collector built on this env then
        starts from the rows it was carrying when the checkpoint was written.
        """
        keys = (*self.row_keys, "outcome", "done", "terminated")
        self._pending_state = state.select(*keys).to(self.device).clone()

    # ------------------------------------------------------------------ EnvBase API
    def _reset(self, tensordict: TensorDictBase | None, **kwargs) -> TensorDictBase:
        batch = self.batch_size
        count = batch.numel()
        if self._pending_state is not None:
            state, self._pending_state = self._pending_state, None
            state["observation"] = self.observe(state)
            for key in REWARD_PART_KEYS:
                state[key] = torch.zeros(batch, device=self.device)
            return state
        scenario = tensordict.get("scenario", None) if tensordict is not None else None
        if scenario is None:
            return self.fresh_rows(count).reshape(batch)
        return self.start_rows(
            scenario["aircraft_state"].reshape(count, 7),
            scenario["destination_state"].reshape(count, 4),
            scenario["destination_speed"].reshape(count),
            scenario["destination_turn_rate"].reshape(count),
        ).reshape(batch)

    def maybe_reset(self, tensordict: TensorDictBase) -> TensorDictBase:
        """New episodes in the rows of ``tensordict`` (a ``step_mdp`` result) that are done, the others kept:
        ``EnvBase.maybe_reset``'s fields and values from the same draws (tested, for batches of a multiple of 64).

        TorchRL's path builds a whole batch of new rows (:meth:`_reset`) and merges the done ones field by field
        with tensordict's ``where``. This one draws the whole batch (the random stream stays the same), builds the
        done rows' fields that do not start at zero (:meth:`start_fields`, padded to whole vectors as in
        :meth:`fresh_rows`) and writes them into each field out of place, zeroing the rest there: every other field
        of a new episode starts at zero (:meth:`start_rows`), and a field new rows lack (a policy's output, the
        collector's episode ids) is zeroed in them, as TorchRL pads it (unless every row is done: TorchRL then
        keeps it, and so does this). A reset restoring saved rows (:meth:`restore_on_next_reset`) takes TorchRL's
        path.
        """
        if self._pending_state is not None:
            return super().maybe_reset(tensordict)
        done = tensordict.get("done")
        if not bool(done.any()):
            return tensordict
        count = self.batch_size.numel()
        rows = done.reshape(-1).nonzero().squeeze(-1)
        if rows.numel() == count:  # TorchRL's whole reset: the new rows' fields replace those they have
            return tensordict.update(self.fresh_rows(count))
        present = tensordict.keys()
        if not all(key in present for key in ZERO_AT_START):  # a start field to add (zero in the other rows)
            put_rows(tensordict, self.fresh_rows(count, rows), rows)
            return tensordict
        padded = padded_rows(rows)
        starts = self.start_fields(*(field[padded] for field in self.draw_starts(count)))
        put_rows(tensordict, starts[:rows.numel()], rows)
        return tensordict

    def draw_starts(self, count: int) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
        """``count`` new episodes' initial conditions from the env's generator: aircraft state ``(count, 7)``,
        destination state ``(count, 4)``, destination speed and turn rate ``(count,)``."""
        destination_state = self._destination_start.expand(count, 4).clone()
        destination_speed, destination_turn_rate = self.params.destination.initial_motion(
            count, self._generator, self.device
        )
        aircraft_state = sample_initial_aircraft(
            count, self.params.initial_state, destination_state, self._generator, self.device
        )
        return aircraft_state, destination_state, destination_speed, destination_turn_rate

    def fresh_rows(self, count: int, rows: torch.Tensor | None = None) -> TensorDictBase:
        """``count`` new episodes drawn from the env's generator (:meth:`draw_starts`; flat batch ``[count]``), as
        a reset returns them; with ``rows`` (indices into them, ascending) those rows only, drawn as part of the
        ``count``.

        The gymnasium vector env restarts only its finished rows with ``fresh_rows(finished)``. With ``rows`` the
        rows are built padded to whole vectors (:func:`agrl.core.compiled.padded_rows`), so that their
        observations are bit for bit those of the whole batch.
        """
        starts = self.draw_starts(count)
        if rows is None:
            return self.start_rows(*starts)
        padded = padded_rows(rows)
        return self.start_rows(*(field[padded] for field in starts))[:rows.numel()]

    def start_fields(
        self, aircraft_state: torch.Tensor, destination_state: torch.Tensor, destination_speed: torch.Tensor,
        destination_turn_rate: torch.Tensor,
    ) -> TensorDictBase:
        """The fields of rows at the start of an episode from these initial conditions (flat batch) that need not
        be zero: the initial conditions, the held targets of an agent holding them, and the observation. Every
        other field of :meth:`start_rows` is zero (:data:`ZERO_AT_START`)."""
        count = aircraft_state.shape[0]
        state = TensorDict(
            {
                "aircraft_state": aircraft_state,
                "destination_state": destination_state,
                "destination_speed": destination_speed,
                "destination_turn_rate": destination_turn_rate,
            },
            batch_size=[count],
            device=self.device,
        )
        if self.holds_targets:  # hold what the aircraft flies until the first instruction
            state[HELD_TARGETS_KEY] = aircraft_state[..., _HELD_FIELDS].clone()
        memory = {} if self.holds_targets else {"last_action": torch.zeros(count, dtype=torch.int64,
                                                                           device=self.device)}
        state["observation"] = self.observe({**state, **memory})
        return state

    def start_rows(
        self, aircraft_state: torch.Tensor, destination_state: torch.Tensor, destination_speed: torch.Tensor,
        destination_turn_rate: torch.Tensor,
    ) -> TensorDictBase:
        """Rows at the start of an episode from these initial conditions (flat batch): :meth:`start_fields`, every
        other field zero (:data:`ZERO_AT_START`)."""
        state = self.start_fields(aircraft_state, destination_state, destination_speed, destination_turn_rate)
        for key, (dtype, *shape) in ZERO_AT_START.items():
            state[key] = torch.zeros(aircraft_state.shape[0], *shape, dtype=dtype, device=self.device)
        return state

    def _step(self, tensordict: TensorDictBase) -> TensorDictBase:
        destination_speed, destination_turn_rate = self.next_destination_motion(
            tensordict["destination_speed"], tensordict["destination_turn_rate"])
        return self.transition(tensordict, destination_speed, destination_turn_rate)

    def next_destination_motion(self, speed: torch.Tensor,
                                turn_rate: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """The destination's speed and turn rate for the next decision of rows now moving at these: the irregular
        destination's random redraw (from the env's generator, one draw of each kind per row), else unchanged."""
        if self.params.destination.name is not MotionKind.IRREGULAR:
            return speed, turn_rate
        motion = self.params.destination
        return redraw_irregular_motion(speed, turn_rate, motion.change_probability, motion.speed_range,
                                       motion.max_turn_rate, self._generator)

    def transition(
        self, state: TensorDictBase, destination_speed: torch.Tensor, destination_turn_rate: torch.Tensor
    ) -> TensorDictBase:
        """One decision from ``state`` (with its ``action``) under the given destination motion.

        Deterministic: the environment's step is this plus the irregular destination's
        random redraw. The policy-reuse step calls it to re-simulate episodes exactly
        as the environment would. Works for any batch shape of ``state``.
        """
        targets = None
        if self.holds_targets:
            targets = self.targets_after(state)
            result = self.simulator.fly_targets(
                state["aircraft_state"], state["destination_state"], destination_speed, destination_turn_rate,
                targets[0],
            )
        else:
            result = self.simulator(
                state["aircraft_state"], state["destination_state"], destination_speed, destination_turn_rate,
                state["action"].long(),
            )
        return self.complete_transition(state, result, destination_speed, destination_turn_rate, targets)

    def complete_transition(
        self, state: TensorDictBase, result: DecisionResult, destination_speed: torch.Tensor,
        destination_turn_rate: torch.Tensor, targets: tuple[torch.Tensor, torch.Tensor] | None = None,
    ) -> TensorDictBase:
        """The rest of :meth:`transition` once the simulator's ``result`` for ``state``'s action is known.

        The policy-reuse step records the simulator's results while it searches, then completes the kept
        episodes' transitions with this in one batch (any batch shape) instead of simulating them again.
        ``targets``: for an agent holding targets, :meth:`targets_after` of ``state`` if the caller has it (else it
        is computed here).
        """
        action = state["action"].long()
        step_count = state["step_count"] + 1
        outcome = decision_outcome(result.outcome, step_count, self.params.max_decisions)
        terminal = outcome != Outcome.RUNNING
        next_state = TensorDict(
            {
                "aircraft_state": result.aircraft_state,
                "destination_state": result.destination_state,
                "destination_speed": destination_speed,
                "destination_turn_rate": destination_turn_rate,
                "last_action": action,
                "action_before_last": state["last_action"],
                "step_count": step_count,
                "outcome": outcome,
                "done": terminal.unsqueeze(-1),
                "terminated": terminal.unsqueeze(-1),
            },
            batch_size=state.batch_size,
            device=self.device,
        )
        # An instruction is a decision that changes the maneuver being flown, or a held target.
        if self.holds_targets:
            next_state[HELD_TARGETS_KEY], instruction = targets if targets is not None else self.targets_after(state)
        else:
            instruction = action != state["last_action"]
        # Equation 5 plus the switch cost, and its parts (logged; they sum to the reward).
        reward, parts = step_reward(
            outcome, state["aircraft_state"], state["destination_state"], state["last_action"],
            state["action_before_last"], action, result.aircraft_state, result.destination_state, self.params.reward,
            instruction,
        )
        next_state.update(parts)
        next_state["reward"] = reward.unsqueeze(-1)
        next_state["episode_return"] = state["episode_return"] + reward
        next_state["instruction_count"] = state["instruction_count"] + instruction.long()
        next_state["observation"] = self.observe(next_state)
        return next_state
