"""Policy reuse by destination position prediction (the paper's Algorithm 1) as a replay-buffer transform.

When collected data is added to the replay buffer (``rb.extend`` calls
:meth:`PolicyReuseTransform.inv`), each episode with rows in the batch whose start
is known (in this batch, or kept from an earlier one: each env's rows since its
episode's start are kept until the episode ends) is, if it was selected with
probability ``e`` when it started, re-played with the frozen baseline agent B:

1. The destination's trajectory is known: recorded in the batch, and extended
   past the episode's end by its motion model (constant speed and turn rate).
2. For every candidate termination step ``t_n`` (a grid over the decision
   budget) the aircraft is re-simulated from the episode's start. At each step
   ``n`` the baseline sees the state with the destination fields replaced by the
   destination's position at ``t_n`` (equation 20), and picks its deterministic
   action. The step itself is the real environment's transition: the real,
   moving destination, the real rewards and done flags (Algorithm 1 lines 17-29).
   A candidate's rollout stops at success, at failure, or one candidate spacing
   after ``t_n`` (Algorithm 1 runs ``n`` to ``t_n``; the spacing lets consecutive
   candidates tile the time axis).
3. If some candidate succeeds, the episode's stored tuples are replaced by the
   successful re-played episode of the earliest (``keep="earliest"``) or latest
   ``t_n``; if none does, the agent's own data is kept. ``e`` drops by ``k`` for
   every selected episode and stops at 0 (Algorithm 1 line 32).

Two shortcuts, off by default (``relabel_unfinished=False``, ``relabel_own_successes=False``), skip the search
of an episode still running at the batch's end (it is searched once, in the batch where it ends: Algorithm 1
line 6 searches after Z ran the complete episode) or of one Z itself flew to a success; their rows stay Z's.

The candidates run in a few waves (the earliest t_n first for ``earliest``), all
episodes together in each: a time loop per wave, with finished rows dropped as
they end, and no Python loop over episodes or candidates. The loop records each
row's actions and simulated states; the kept rollouts' transitions are completed
from that record in one batch (no second simulation). Stored tuples carry the
real destination fields, so PPO trains the new agent on its own task. The transform never writes into its input.

Actions of relabelled rows come from B, not from the policy being trained, so the
PPO quantities are recomputed for them by ``ppo_targets(trajectories, valid)``
(in the trainer, :func:`relabelled_ppo_targets`: a behaviour log-probability,
values and GAE advantages on the re-played trajectories; ``valid`` marks the
rows that are not padding).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import NamedTuple

import torch
from tensordict import TensorDict, TensorDictBase
from torchrl.envs import ExplorationType, Transform, set_exploration_type
from torchrl.modules import ProbabilisticActor

from agrl.core.destinations import DestinationState, move_destination
from agrl.core.observation import in_destination_frame, observation_function
from agrl.core.simulation import DecisionResult
from agrl.core.termination import Outcome
from agrl.envs.guidance import STATE_KEYS, GuidanceEnv
from agrl.rl.models import logits_network

#: Entries kept in the buffer for PPO when the transform is active.
PPO_KEYS = ("observation", "action", "action_log_prob", "state_value", "advantage", "value_target", "relabelled")
TRAJECTORY_KEY = ("collector", "traj_ids")
#: Entries of the rows kept from one batch to the next (what the search and the prediction read).
CARRY_KEYS = (*STATE_KEYS, *[("next", key) for key in ("aircraft_state", "destination_state", "destination_speed",
                                                      "destination_turn_rate", "done")])


def candidate_steps(max_decisions: int, stride: int, max_candidates: int) -> torch.Tensor:
    """The grid of candidate termination steps ``t_n`` in ``[stride, max_decisions]``, at most ``max_candidates``."""
    if not 1 <= stride <= max_decisions:
        raise ValueError(f"candidate_stride={stride} is not allowed: between 1 and max_decisions={max_decisions}")
    if max_candidates < 1:
        raise ValueError(f"max_candidates={max_candidates} is not allowed: >= 1")
    grid = torch.arange(stride, max_decisions + 1, stride)
    if grid.numel() > max_candidates:
        pick = torch.linspace(0, grid.numel() - 1, max_candidates).round().long().unique()
        grid = grid[pick]
    return grid


def candidate_waves(candidates: int, keep: str) -> list[torch.Tensor]:
    """The search's waves: candidate indices in the order they can be kept, in groups of 2, 2, 4, 8, ...

    With ``keep="earliest"`` the first waves hold the smallest t_n, whose rollouts are short; an episode
    whose earliest candidates succeed never runs its long, late ones. ``latest`` runs the grid backwards.
    """
    order = torch.arange(candidates) if keep == "earliest" else torch.arange(candidates - 1, -1, -1)
    waves, start, size = [], 0, 2
    while start < candidates:
        waves.append(order[start:start + size])
        start += size
        size = size if start < 4 else 2 * size
    return waves


@torch.no_grad()
def relabelled_ppo_targets(
    trajectories: TensorDictBase, valid: torch.Tensor, *, critic: Callable, advantage: Callable,
    actor: ProbabilisticActor | None = None,
) -> TensorDictBase:
    """What PPO needs for re-played trajectories ``(episodes, steps)``, computed on the ``valid`` rows only.

    Each episode's valid rows are its first steps, in order (``valid`` is a prefix of every row of the table),
    so the observation after step n is the one step n + 1 acts on.

    The behaviour log-probability is B's (``baseline_log_prob``), or, with ``actor`` given, that actor's
    log-probability of B's action (``method.behaviour_log_prob=current``). The critic runs once on each valid
    row's observation and on the observation after each episode's last row (padding gets a value of 0 and is
    marked terminal by the caller, so it never reaches an advantage), then ``advantage`` (a value estimator
    built without a value network, e.g. ``GAE(value_network=None)``) computes the advantages and value targets
    along the time dimension.
    """
    device = valid.device
    rows = trajectories[valid]
    if actor is None:
        trajectories["action_log_prob"] = trajectories["baseline_log_prob"]
    else:
        log_prob = torch.zeros(valid.shape, device=device)
        log_prob[valid] = actor.get_dist(rows).log_prob(rows["action"])
        trajectories["action_log_prob"] = log_prob
    value = torch.zeros(*valid.shape, 1, device=device)
    value[valid] = critic(rows.select("observation"))["state_value"]
    next_value = torch.zeros_like(value)
    next_value[:, :-1] = value[:, 1:]  # the value after step n is the value at step n + 1 ...
    episode = valid.any(1).nonzero().squeeze(-1)
    last = valid.sum(1)[episode] - 1
    after_last = trajectories["next", "observation"][episode, last]  # ... except after an episode's last row
    next_value[episode, last] = critic(TensorDict({"observation": after_last}, [episode.numel()]))["state_value"]
    trajectories.set("state_value", value)
    trajectories.set(("next", "state_value"), next_value)
    return advantage(trajectories)


class PolicyReuseTransform(Transform):
    """Rewrites collected episodes with a frozen baseline actor (Algorithm 1); see the module docstring."""

    def __init__(
        self,
        baseline_actor: torch.nn.Module,
        env: GuidanceEnv,
        *,
        ppo_targets: Callable[[TensorDictBase, torch.Tensor], TensorDictBase],
        initial_selection_factor: float,  # Algorithm 1's knobs: no defaults here, conf/method/reuse.yaml has them
        selection_decay: float,
        candidate_stride: int,
        max_candidates: int,
        keep: str,
        max_rows: int | None = None,
        seed: int = 0,
        relabel_unfinished: bool = True,
        relabel_own_successes: bool = True,
        baseline_observation: str = "relative",
    ):
        super().__init__(in_keys=[], out_keys=[])
        if keep not in ("earliest", "latest"):
            raise ValueError(f"keep={keep!r} is not allowed: earliest or latest")
        self.baseline_actor = baseline_actor.eval().requires_grad_(False)
        # B's own input (its checkpoint's agent.observation), which may differ from Z's (the env's).
        self.baseline_observation = baseline_observation
        self._baseline_input = observation_function(baseline_observation)
        self._baseline_logits = logits_network(self.baseline_actor)
        self.env = env
        self.selection_factor = float(initial_selection_factor)
        self.selection_decay = float(selection_decay)
        self.keep = keep
        self.ppo_targets = ppo_targets
        self.max_rows = max_rows
        # Shortcuts off by default (not the paper's semantics; the module docstring): False skips the search
        # of an episode still running at the batch's end (it is searched once, in the batch where it ends) ...
        self.relabel_unfinished = relabel_unfinished
        # ... and of an episode the agent itself flew to a success (its own rows are kept).
        self.relabel_own_successes = relabel_own_successes
        self.candidates = candidate_steps(env.params.max_decisions, candidate_stride, max_candidates).to(env.device)
        self.generator = torch.Generator(device=env.device).manual_seed(seed + 7_919)
        self._statistics: dict[str, float] = {}
        # Rows of each env's unfinished episode (since its start), kept for the next batch: flat, env after env.
        self._carry: TensorDictBase | None = None
        self._carry_lengths: torch.Tensor | None = None  # (envs,) rows kept per env, < max_decisions
        self._carry_selected: torch.Tensor | None = None  # (envs,) whether that episode was selected

    # ------------------------------------------------------------------ state for checkpoints
    def state_dict(self, *args, **kwargs) -> dict:
        """Plain tensors and dicts (checkpoints are read with ``torch.load(weights_only=True)``)."""
        state = {"selection_factor": self.selection_factor, "generator": self.generator.get_state()}
        if self._carry is not None:
            state["carry"] = {"rows": self._carry.to_dict(), "lengths": self._carry_lengths.clone(),
                              "selected": self._carry_selected.clone()}
        return state

    def load_state_dict(self, state: dict, *args, **kwargs) -> None:
        self.selection_factor = float(state["selection_factor"])
        self.generator.set_state(state["generator"])
        carry = state.get("carry")
        if carry is None:
            self._carry = self._carry_lengths = self._carry_selected = None
            return
        device = self.env.device
        lengths = carry["lengths"].to(device)
        self._carry = TensorDict(carry["rows"], batch_size=[int(lengths.sum())], device=device)
        self._carry_lengths, self._carry_selected = lengths, carry["selected"].to(device)

    def last_statistics(self) -> dict[str, float]:
        """Dashboard scalars of the last call (``train/reuse_fraction``, ``train/e``, ...)."""
        return dict(self._statistics)

    # ------------------------------------------------------------------ Transform API
    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        return tensordict  # sampling returns stored rows unchanged

    def _call(self, tensordict: TensorDictBase) -> TensorDictBase:
        return tensordict

    @torch.no_grad()
    def _inv_call(self, tensordict: TensorDictBase) -> TensorDictBase:
        return self.relabel(tensordict)

    # ------------------------------------------------------------------ Algorithm 1
    @torch.no_grad()
    def relabel(self, rows: TensorDictBase) -> TensorDictBase:
        """Flat collector rows -> own rows of untouched episodes + re-played rows of relabelled ones."""
        start_time = time.perf_counter()
        device = rows.device
        if rows.batch_dims != 1:
            raise ValueError(f"PolicyReuseTransform expects flat rows (one batch dimension), got {rows.batch_size}")
        # Each env's rows since its episode's start: the rows kept from earlier batches, then this batch's.
        known, per_env, in_batch, episode_ids, carried = self._with_carried_rows(rows)
        traj_ids = episode_ids[in_batch]  # the episode of every row of this batch
        starts = (known["step_count"] == 0).nonzero().squeeze(-1)
        new = in_batch[starts]
        # Episodes starting in this batch, each selected with probability e (line 10-11); an episode carried
        # over from an earlier batch keeps the choice made when it started.
        selected = torch.zeros(starts.numel(), dtype=torch.bool, device=device)
        draws = torch.rand(int(new.sum()), generator=self.generator, device=device) < self.selection_factor
        selected[new] = draws
        selected[~new] = carried[starts[~new]]
        self._keep_unfinished(known, per_env, starts, selected)
        # The share of this batch's rows whose episode's start is known: the rows that can be relabelled.
        has_start = torch.zeros(int(episode_ids[-1]) + 1, dtype=torch.bool, device=device)
        has_start[episode_ids[starts]] = True
        relabellable = float(has_start[traj_ids].float().mean())
        searched = selected & self._searchable(known, rows, in_batch, starts, episode_ids)
        starts = starts[searched]
        episodes = int(starts.numel())
        self.selection_factor = max(0.0, self.selection_factor - self.selection_decay * int(draws.sum()))

        relabelled_rows = None
        succeeded = torch.zeros(episodes, dtype=torch.bool, device=device)
        dropped = torch.zeros_like(succeeded)
        if episodes:
            trajectory, motion = self._destination_prediction(known, starts, episode_ids)
            start_rows = known[starts]
            winner_step, winner_index, record = self._search_recorded(start_rows, trajectory, motion)
            found, dropped = self._fitting(winner_index >= 0, winner_step, traj_ids, episode_ids[starts],
                                           rows.numel())
            succeeded |= dropped  # found, but their rows would fall past max_rows: neither own nor re-played
            if found.numel():
                kept = SearchRecord(*(field[found] for field in record))
                relabelled_rows = self._relabelled_trajectories(start_rows[found], motion[found], winner_step[found],
                                                                kept)
                succeeded[found] = True
        replaced_ids = episode_ids[starts[succeeded]]
        keep_own = ~torch.isin(traj_ids, replaced_ids)
        own = rows[keep_own].select(*[key for key in PPO_KEYS if key != "relabelled"])
        own["relabelled"] = torch.zeros(own.batch_size, dtype=torch.bool, device=device)
        output = own if relabelled_rows is None else torch.cat([own, relabelled_rows], 0)
        if self.max_rows is not None and output.numel() > self.max_rows:
            output = output[: self.max_rows]  # drops the tail of the re-played rows only
        # Counted after the cut to ``max_rows``: the share of what the buffer really receives.
        relabelled_count = int(output["relabelled"].sum())
        self._statistics = {
            "train/e": self.selection_factor,
            "train/reuse_fraction": relabelled_count / max(output.numel(), 1),
            "train/reuse_episodes_selected": int(selected.sum()),
            "train/reuse_episodes_searched": episodes,
            "train/reuse_episodes_carried": int((~new[selected]).sum()),
            "train/reuse_relabellable_fraction": relabellable,
            "train/reuse_episodes_relabelled": int((succeeded & ~dropped).sum()),
            "time/reuse_relabel_seconds": time.perf_counter() - start_time,
        }
        return output

    def _with_carried_rows(
        self, rows: TensorDictBase
    ) -> tuple[TensorDictBase, torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
        """This batch's rows with, in front of each env's, the rows kept from its episode's earlier batches.

        Returns the rows (``CARRY_KEYS``, env after env), their count per env, a mask of the ones from this batch,
        an episode id per row (ascending; an episode is contiguous: it begins at ``step_count == 0`` or at an
        env's first row) and, per row, whether its episode was selected in the batch where it started (on kept
        rows; False on this batch's).
        Kept rows are used only when this batch continues them (the next step count and aircraft state).
        """
        device = rows.device
        envs = self.env.batch_size.numel()
        if rows.numel() % envs:
            raise ValueError(f"PolicyReuseTransform expects {envs} envs x steps rows, got {rows.numel()} rows")
        steps = rows.numel() // envs
        batch = rows.select(*CARRY_KEYS)
        first = torch.arange(envs, device=device) * steps
        lengths = torch.zeros(envs, dtype=torch.long, device=device)
        if self._carry is not None and self._carry_lengths.numel() == envs:
            end = torch.cumsum(self._carry_lengths, 0) - 1
            last = self._carry[end.clamp(min=0)] if self._carry.numel() else None
            if last is not None:
                continues = (
                    (self._carry_lengths > 0)
                    & (batch["step_count"][first] == last["step_count"] + 1)
                    & (batch["aircraft_state"][first] == last["next", "aircraft_state"]).all(-1)
                )
                lengths = torch.where(continues, self._carry_lengths, 0)
        carry_rows = self._carry.numel() if self._carry is not None and lengths.any() else 0
        source = torch.cat([self._carry, batch]) if carry_rows else batch
        offset = torch.cumsum(self._carry_lengths, 0) - self._carry_lengths if carry_rows else lengths
        per_env = lengths + steps
        env = torch.repeat_interleave(torch.arange(envs, device=device), per_env)
        position = torch.arange(int(per_env.sum()), device=device) - (torch.cumsum(per_env, 0) - per_env)[env]
        kept = position < lengths[env]
        index = torch.where(kept, offset[env] + position, carry_rows + env * steps + position - lengths[env])
        known = source[index]
        boundary = (known["step_count"] == 0) | (position == 0)
        episode_ids = torch.cumsum(boundary.long(), 0) - 1
        carried = kept & self._carry_selected[env] if carry_rows else kept
        return known, per_env, ~kept, episode_ids, carried

    def _searchable(
        self, known: TensorDictBase, rows: TensorDictBase, in_batch: torch.Tensor, starts: torch.Tensor,
        episode_ids: torch.Tensor,
    ) -> torch.Tensor:
        """Per episode start: whether its search runs (all True unless a shortcut of ``__init__`` is on)."""
        searchable = torch.ones(starts.numel(), dtype=torch.bool, device=starts.device)
        if self.relabel_unfinished and self.relabel_own_successes:
            return searchable
        # Each episode's last row (episode ids ascend, one contiguous run of rows each).
        last_row = torch.searchsorted(episode_ids, episode_ids[starts], right=True) - 1
        ended = known["next", "done"].reshape(-1)[last_row]
        if not self.relabel_unfinished:
            searchable &= ended
        if not self.relabel_own_successes:
            # An ended episode's last row is in this batch (kept rows are those of unfinished episodes).
            outcome = torch.full((known.numel(),), int(Outcome.RUNNING), dtype=torch.long, device=starts.device)
            outcome[in_batch] = rows["next", "outcome"].reshape(-1).long()
            searchable &= ~(ended & (outcome[last_row] == Outcome.SUCCESS))
        return searchable

    def _keep_unfinished(
        self, known: TensorDictBase, per_env: torch.Tensor, starts: torch.Tensor, selected: torch.Tensor
    ) -> None:
        """Keep the rows of each env's last episode for the next batch, if it has not ended and its start is known.

        At most ``max_decisions - 1`` rows per env: an episode ends at its decision budget.
        """
        device = known.device
        last_rows = torch.cumsum(per_env, 0) - 1
        first_rows = last_rows - per_env + 1
        # Each env's last start (starts ascend, envs are contiguous): the start just before its last row.
        position = torch.searchsorted(starts, last_rows, right=True) - 1
        padded = torch.cat([starts, starts.new_full((1,), -1)])  # index -1: no start in the rows at all
        last_start = torch.where(position >= 0, padded[position], -1)
        unfinished = ~known["next", "done"].reshape(-1)[last_rows] & (last_start >= first_rows)
        lengths = torch.where(unfinished, last_rows - last_start + 1, 0)
        env = torch.repeat_interleave(torch.arange(per_env.numel(), device=device), lengths)
        offset = torch.arange(int(lengths.sum()), device=device) - (torch.cumsum(lengths, 0) - lengths)[env]
        self._carry = known[last_start[env] + offset].clone()
        self._carry_lengths = lengths
        self._carry_selected = unfinished & torch.cat([selected, selected.new_zeros(1)])[position]

    def _destination_prediction(
        self, rows: TensorDictBase, starts: torch.Tensor, traj_ids: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """Destination state at every decision 0..budget for each selected episode, and its motion per step.

        Returns ``trajectory (E, budget + 1, 4)`` and ``motion (E, budget, 2)`` (speed m/s, turn rate rad/s).
        Rows of one episode are contiguous in the collector's flat (env-major) layout.
        """
        budget = self.env.params.max_decisions
        count = rows.numel()
        steps = torch.arange(budget, device=rows.device)
        index = (starts[:, None] + steps[None, :]).clamp(max=count - 1)
        recorded = (traj_ids[index] == traj_ids[starts][:, None]) & (starts[:, None] + steps[None, :] < count)
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
        airspace = self.env.params.simulation.airspace
        period = self.env.params.simulation.decision_period
        for step in range(budget):
            # Recorded positions where known; beyond the episode's end, the motion model (one exact arc per decision).
            predicted = move_destination(
                DestinationState.from_tensor(states[-1]), motion[:, step, 0], motion[:, step, 1], period,
                (airspace.x_min, airspace.x_max), (airspace.y_min, airspace.y_max),
            ).to_tensor()
            states.append(torch.where(recorded_after[:, step, None], after[:, step], predicted))
        return torch.stack(states, 1), motion

    def _baseline_actions(self, state: TensorDictBase, predicted_destination: torch.Tensor) -> torch.Tensor:
        """B's deterministic action on the state whose destination fields are the prediction (equation 20)."""
        return self._baseline_mode(self._predicted_observation(state["aircraft_state"], predicted_destination,
                                                                state["last_action"]))

    def _predicted_observation(
        self, aircraft_state: torch.Tensor, predicted_destination: torch.Tensor, last_action: torch.Tensor
    ) -> torch.Tensor:
        """B's input with the destination fields replaced by the prediction (equation 20).

        The relative observation describes the aircraft from the destination it is given, so the prediction goes
        in as it is. With the absolute one (equation 4), B has only seen the fixed destination at the origin: the
        state is moved into the predicted destination's frame first (section 5.1, :func:`in_destination_frame`).
        """
        simulation = self.env.params.simulation
        if self.baseline_observation == "absolute":
            aircraft_state, predicted_destination = in_destination_frame(aircraft_state, predicted_destination)
        return self._baseline_input(aircraft_state, predicted_destination, last_action, simulation.airspace,
                                    simulation.limits)

    def _baseline_mode(self, observation: torch.Tensor) -> torch.Tensor:
        """B's action in deterministic mode: the mode of its distribution (the argmax for a categorical)."""
        return self._baseline_mode_and_log_prob(observation)[0]

    def _baseline_mode_and_log_prob(self, observation: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """B's deterministic action and its log-probability under B, from one forward pass (the search keeps
        both, so that the kept rows' B log-probability needs no second pass of B)."""
        if self._baseline_logits is not None:
            # What the actor computes in DETERMINISTIC mode (Categorical(logits).mode), without its TensorDict
            # and distribution wrappers: the search calls this once per time step (tested equal to the actor).
            logits = self._baseline_logits(observation)
            # Categorical(logits=logits), op for op: normalised logits; the mode is their softmax's argmax and
            # the log-probability of an action its normalised logit.
            normalised = logits - logits.logsumexp(dim=-1, keepdim=True)
            action = torch.softmax(normalised, dim=-1).argmax(dim=-1)
            return action, normalised.gather(-1, action[..., None]).squeeze(-1)
        query = TensorDict({"observation": observation}, batch_size=observation.shape[:-1], device=observation.device)
        with set_exploration_type(ExplorationType.DETERMINISTIC):
            action = self.baseline_actor(query)["action"]
        return action, self.baseline_actor.get_dist(query).log_prob(action)

    def _search(
        self, start_rows: TensorDictBase, trajectory: torch.Tensor, motion: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """Roll out the (episode, t_n) candidates; return the kept candidate's arrival step and index.

        ``winner_index`` is -1 for episodes where no candidate succeeded (see :meth:`_search_recorded`).
        """
        winner_step, winner_index, _ = self._search_recorded(start_rows, trajectory, motion)
        return winner_step, winner_index

    def _search_recorded(
        self, start_rows: TensorDictBase, trajectory: torch.Tensor, motion: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor, SearchRecord]:
        """:meth:`_search`, also returning the kept candidate's recorded rollout of each episode.

        The candidates run in waves (:func:`candidate_waves`), in the order they would be kept (earliest:
        ascending t_n): an episode with a success in one wave has its kept candidate there, so its later
        waves are not run. Within a wave all candidates of all pending episodes run in one batch.
        """
        device = trajectory.device
        episodes, candidates = trajectory.shape[0], self.candidates.numel()
        spacing = int(self.candidates[1] - self.candidates[0]) if candidates > 1 else 1
        # The kept candidate per episode: index into the grid (earliest = smallest, latest = largest).
        sentinel = candidates if self.keep == "earliest" else -1
        best = torch.full((episodes,), sentinel, dtype=torch.long, device=device)
        arrival = torch.zeros(episodes, candidates, dtype=torch.long, device=device)
        budget = self.env.params.max_decisions
        aircraft = start_rows["aircraft_state"]
        record = SearchRecord(
            action=torch.zeros(episodes, budget, dtype=torch.long, device=device),
            aircraft_state=aircraft.new_zeros(episodes, budget, aircraft.shape[-1]),
            destination_state=aircraft.new_zeros(episodes, budget, start_rows["destination_state"].shape[-1]),
            baseline_log_prob=aircraft.new_zeros(episodes, budget),
        )
        pending = torch.arange(episodes, device=device)
        for wave in candidate_waves(candidates, self.keep):
            if pending.numel() == 0:
                break
            wave = wave.to(device)
            self._search_wave(start_rows, trajectory, motion, pending, wave, spacing, best, arrival, record)
            pending = pending[best[pending] == sentinel]
        found = (best >= 0) & (best < candidates)
        winner_index = torch.where(found, best, -1)
        winner_arrival = arrival.gather(1, winner_index.clamp(min=0)[:, None]).squeeze(1)
        return torch.where(found, winner_arrival, 0), winner_index, record

    def _search_wave(
        self, start_rows: TensorDictBase, trajectory: torch.Tensor, motion: torch.Tensor, pending: torch.Tensor,
        wave: torch.Tensor, spacing: int, best: torch.Tensor, arrival: torch.Tensor, record: SearchRecord,
    ) -> None:
        """One time loop over the rows ``(episode, candidate)`` of the ``pending`` episodes and the ``wave``'s
        candidates; updates ``best`` and ``arrival`` in place, and copies the rollout of each episode's kept
        candidate (when this wave holds it) into ``record``.

        The loop works on plain tensors: B's observation and mode, the simulator, the end checks. The rest of
        the environment's transition (reward, observation of the real destination) is computed afterwards for
        the kept rollouts only (:meth:`_relabelled_trajectories`).
        """
        device = trajectory.device
        size = wave.numel()
        episode = pending.repeat_interleave(size)
        candidate = wave.repeat(pending.numel())
        budget = self.env.params.max_decisions
        target_step = self.candidates[candidate]
        # Steps each row may run: to its candidate's limit, or to the end of the episode's decision budget.
        stop = torch.minimum((target_step + spacing).clamp(max=budget), budget - start_rows["step_count"][episode])
        steps = int(stop.max())
        predicted = trajectory[episode, target_step]
        aircraft = start_rows["aircraft_state"][episode]
        destination = start_rows["destination_state"][episode]
        last_action = start_rows["last_action"][episode].long()
        reduce = "amin" if self.keep == "earliest" else "amax"
        # The running rows, compacted as rows end: their row number, episode, candidate, prediction and stop.
        alive = torch.arange(episode.numel(), device=device)
        log = []  # per step: the running rows, B's actions and the simulator's states after the step
        for step in range(steps):
            if alive.numel() == 0:
                break
            action, log_prob = self._baseline_mode_and_log_prob(
                self._predicted_observation(aircraft, predicted, last_action))
            result = self._simulate(aircraft, destination, motion[episode, step, 0], motion[episode, step, 1], action)
            log.append((alive, action, result.aircraft_state, result.destination_state, log_prob))
            success = result.outcome == Outcome.SUCCESS
            if bool(success.any()):
                arrival[episode[success], candidate[success]] = step + 1
                best.scatter_reduce_(0, episode[success], candidate[success], reduce=reduce)
            # Still running: not ended by the simulator (success, airspace), the budget, or the candidate's limit;
            # and not on the far side of its episode's kept success (it can no longer be the one kept).
            running = (result.outcome == Outcome.RUNNING) & (step + 1 < stop)
            running &= candidate < best[episode] if self.keep == "earliest" else candidate > best[episode]
            aircraft, destination, last_action = result.aircraft_state, result.destination_state, action
            if bool(running.all()):
                continue
            keep = running.nonzero().squeeze(-1)
            alive, episode, candidate, predicted, stop = (
                field[keep] for field in (alive, episode, candidate, predicted, stop))
            aircraft, destination, last_action = aircraft[keep], destination[keep], last_action[keep]
        if not log:
            return
        # Episodes whose kept candidate is in this wave (they had none before it): keep that row's rollout.
        decided = (best[pending] >= wave.min()) & (best[pending] <= wave.max())
        position = torch.full((int(self.candidates.numel()),), -1, dtype=torch.long, device=device)
        position[wave] = torch.arange(size, device=device)
        kept_episode = pending[decided]
        kept_row = decided.nonzero().squeeze(-1) * size + position[best[kept_episode]]
        episode_of_row = torch.full((pending.numel() * size,), -1, dtype=torch.long, device=device)
        episode_of_row[kept_row] = kept_episode
        rows, actions, aircraft_after, destination_after, log_probs = (
            torch.cat(field) for field in zip(*log, strict=True))
        step_of = torch.repeat_interleave(torch.arange(len(log), device=device),
                                          torch.tensor([entry[0].numel() for entry in log], device=device))
        target = episode_of_row[rows]
        kept = target >= 0
        target, step_of = target[kept], step_of[kept]
        record.action[target, step_of] = actions[kept]
        record.aircraft_state[target, step_of] = aircraft_after[kept]
        record.destination_state[target, step_of] = destination_after[kept]
        record.baseline_log_prob[target, step_of] = log_probs[kept]

    def _simulate(
        self, aircraft: torch.Tensor, destination: torch.Tensor, destination_speed: torch.Tensor,
        destination_turn_rate: torch.Tensor, action: torch.Tensor,
    ) -> DecisionResult:
        """The environment's simulator (as in ``env.transition``), with a single row doubled: a batch of one
        would make the fused simulator recompile (torch.compile specialises sizes 0 and 1), a 10-20 s stall in
        the middle of training."""
        if action.numel() != 1:
            return self.env.simulator(aircraft, destination, destination_speed, destination_turn_rate, action)
        doubled = self.env.simulator(aircraft.repeat(2, 1), destination.repeat(2, 1), destination_speed.repeat(2),
                                     destination_turn_rate.repeat(2), action.repeat(2))
        return DecisionResult(*(field[:1] for field in doubled))

    def _fitting(
        self, found: torch.Tensor, arrival: torch.Tensor, traj_ids: torch.Tensor, episode_ids: torch.Tensor,
        rows: int,
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """Which found episodes to re-play: those whose re-played rows will be inside ``max_rows``.

        The output is the kept own rows, then the re-played episodes in order, cut at ``max_rows``.
        Completing an episode whose rows all fall past the cut is wasted work (early in training, when
        the agent's episodes are short, a large part of it), so those are not completed. Returns the indices
        to re-play and a mask of the found episodes that are dropped (they would have been cut anyway).
        """
        index = found.nonzero().squeeze(-1)
        dropped = torch.zeros_like(found)
        if self.max_rows is None or index.numel() == 0:
            return index, dropped
        ids, counts = torch.unique(traj_ids, return_counts=True)  # sorted ids
        own_kept = rows - int(counts[torch.searchsorted(ids, episode_ids[index])].sum())
        first_row = own_kept + torch.cumsum(arrival[index], 0) - arrival[index]
        fits = first_row < self.max_rows
        dropped[index[~fits]] = True
        return index[fits], dropped

    def _relabelled_trajectories(
        self, start_rows: TensorDictBase, motion: torch.Tensor, arrival: torch.Tensor, record: SearchRecord,
    ) -> TensorDictBase:
        """The kept candidates' episodes as full transitions, from the search's record; flat PPO rows.

        The search recorded, per step, B's action and the simulator's result; the rest of the environment's
        transition (``env.complete_transition``: step count, done flags, equation-5 reward, observation of the
        real destination) is computed here for all kept episodes and steps in one batch ``(episodes, steps)``,
        then PPO's targets. Every recorded rollout ends at its success (step ``arrival - 1``).
        """
        device = motion.device
        episodes = start_rows.numel()
        length = int(arrival.max())
        steps = torch.arange(length, device=device)
        valid = steps[None, :] < arrival[:, None]
        # Padding (after an episode's end) repeats the episode's last transition: finite values, masked below.
        take = torch.minimum(steps[None, :], (arrival - 1)[:, None])
        row = torch.arange(episodes, device=device)[:, None]

        def with_start(start: torch.Tensor, after: torch.Tensor) -> torch.Tensor:
            """Index n: the value before step n (index 0: at S_0); n + 1: after it."""
            return torch.cat([start[:, None], after[:, :length]], 1)

        aircraft = with_start(start_rows["aircraft_state"], record.aircraft_state)
        destination = with_start(start_rows["destination_state"], record.destination_state)
        speed = with_start(start_rows["destination_speed"], motion[..., 0])
        turn_rate = with_start(start_rows["destination_turn_rate"], motion[..., 1])
        # Actions shifted twice: the action before last, the last action, then the action of each step.
        actions = torch.cat([start_rows["action_before_last"].long()[:, None],
                             with_start(start_rows["last_action"].long(), record.action)], 1)
        last_action, action = actions[row, take + 1], actions[row, take + 2]
        changes = (action != last_action).long()
        instructions = start_rows["instruction_count"][:, None] + torch.cumsum(changes, 1) - changes
        state = TensorDict(
            {
                "aircraft_state": aircraft[row, take],
                "destination_state": destination[row, take],
                "destination_speed": speed[row, take],
                "destination_turn_rate": turn_rate[row, take],
                "last_action": last_action.to(start_rows["last_action"].dtype),
                "action_before_last": actions[row, take].to(start_rows["action_before_last"].dtype),
                "step_count": start_rows["step_count"][:, None] + take,
                "episode_return": start_rows["episode_return"][:, None].expand(-1, length),  # set below
                "instruction_count": instructions[row, take],
                "action": action,
            },
            batch_size=[episodes, length], device=device,
        )
        outcome = torch.where(take == (arrival - 1)[:, None], int(Outcome.SUCCESS), int(Outcome.RUNNING))
        result = DecisionResult(aircraft[row, take + 1], destination[row, take + 1], outcome)
        next_state = self.env.complete_transition(state, result, speed[row, take + 1], turn_rate[row, take + 1])
        # The return accumulates step by step, in the environment's order of float additions.
        reward = next_state["reward"].squeeze(-1)
        returns = [start_rows["episode_return"]]
        for step in range(length - 1):
            returns.append(returns[-1] + reward[:, step])
        state["episode_return"] = torch.stack(returns, 1)[row, take]
        next_state["episode_return"] = state["episode_return"] + reward
        state["observation"] = self.env.observe(state)
        # B's log-probability of its action on the observation it acted on (the destination predicted at t_n),
        # as the search computed it.
        state["baseline_log_prob"] = torch.where(valid, record.baseline_log_prob[:, :length], 0.0)
        trajectories = state.set("next", next_state)
        # Rows past an episode's end are padding: mark them terminal so GAE does not mix them in.
        trajectories["next", "done"] = trajectories["next", "done"] | ~valid[..., None]
        trajectories["next", "terminated"] = trajectories["next", "terminated"] | ~valid[..., None]
        trajectories = self.ppo_targets(trajectories, valid)
        flat = trajectories[valid]
        flat["relabelled"] = torch.ones(flat.batch_size, dtype=torch.bool, device=device)
        return flat.select(*PPO_KEYS)


class SearchRecord(NamedTuple):
    """Each episode's kept rollout as the search ran it, per step ``(episodes, max_decisions, ...)``: B's action,
    the simulator's result (the aircraft and destination states after the step) and B's log-probability of its
    action."""

    action: torch.Tensor
    aircraft_state: torch.Tensor
    destination_state: torch.Tensor
    baseline_log_prob: torch.Tensor
