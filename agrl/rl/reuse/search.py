"""The candidate search (Algorithm 1, lines 14-29): for each episode, the earliest or latest successful t_n.

For every candidate termination step ``t_n`` (:func:`candidate_steps`, a grid over the decision budget) the
aircraft is re-simulated from the episode's start: at each step B sees the state with the destination fields
replaced by the destination's predicted state at ``t_n`` and picks its deterministic action, and the step is the
real environment's transition (the real, moving destination). A candidate's rollout stops at success, at failure
(airspace, budget), or one candidate spacing after ``t_n`` (Algorithm 1 runs ``n`` to ``t_n``; the spacing lets
consecutive candidates tile the time axis). :func:`search_candidates` runs all episodes' candidates batched, in
waves (:func:`candidate_waves`), and records the kept candidate's rollout (:class:`SearchRecord`) so that the
completion needs no second simulation.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import NamedTuple

import torch
from tensordict import TensorDictBase

from agrl.core.autopilot import HeldTargets, TargetActionTable, apply_target_action
from agrl.core.simulation import DecisionResult
from agrl.core.termination import Outcome
from agrl.rl.reuse.prediction import BaselinePolicy


def candidate_steps(max_decisions: int, stride: int, max_candidates: int) -> torch.Tensor:
    """The grid of candidate termination steps ``t_n`` in ``[stride, max_decisions]``, at most ``max_candidates``.

    Every ``stride``-th decision; when there are more than ``max_candidates`` of them, that many evenly spread ones
    (the first and the last always in). Returns a strictly increasing int64 tensor ``(candidates,)`` of decisions.
    """
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


class SearchRecord(NamedTuple):
    """Each episode's kept rollout as the search ran it, per step ``(episodes, max_decisions, ...)``: B's action,
    the simulator's result (the aircraft and destination states after the step) and B's log-probability of its
    action. Steps past the kept rollout's end (and episodes without a success) hold zeros."""

    action: torch.Tensor
    aircraft_state: torch.Tensor
    destination_state: torch.Tensor
    baseline_log_prob: torch.Tensor


class SearchResult(NamedTuple):
    """What :func:`search_candidates` found, per episode ``(episodes,)``."""

    arrival: torch.Tensor  #: long: decisions until the kept candidate's success (0 where none succeeded)
    index: torch.Tensor  #: long: the kept candidate's index into the grid (-1 where none succeeded)
    record: SearchRecord  #: the kept candidate's recorded rollout


#: The environment's simulator: ``(aircraft, destination, speed, turn_rate, action) -> DecisionResult``.
Simulator = Callable[..., DecisionResult]


@torch.no_grad()
def search_candidates(
    start_rows: TensorDictBase, trajectory: torch.Tensor, motion: torch.Tensor, *, candidates: torch.Tensor,
    keep: str, baseline: BaselinePolicy, simulator: Simulator, max_decisions: int,
    targets: TargetActionTable | None = None,
) -> SearchResult:
    """Roll out every (episode, t_n) candidate from the episodes' start rows; keep the earliest or latest success.

    ``start_rows`` ``(E,)``: each episode's state S_0 (``aircraft_state``, ``destination_state``, ``last_action``,
    ``step_count``); ``trajectory (E, max_decisions + 1, 4)`` and ``motion (E, max_decisions, 2)``: the predicted
    destination (:func:`~agrl.rl.reuse.prediction.destination_prediction`); ``candidates``: the grid of t_n
    (:func:`candidate_steps`); ``keep``: ``earliest`` or ``latest``; ``simulator``: the environment's
    (``GuidanceEnv.simulator``), called as ``simulator(aircraft, destination, speed, turn_rate, action)``;
    ``targets``: for B holding targets, its action table (``GuidanceEnv.target_table``): each step then sets B's
    held targets (``start_rows["held_targets"]`` at S_0) and the simulator's ``fly_targets`` flies them.

    The candidates run in waves (:func:`candidate_waves`), in the order they would be kept (earliest: ascending
    t_n): an episode with a success in one wave has its kept candidate there, so its later waves are not run.
    Within a wave all candidates of all pending episodes run in one batch, finished rows dropped as they end.
    The result equals running every candidate on its own (tested against a brute-force search).
    """
    if keep not in ("earliest", "latest"):
        raise ValueError(f"keep={keep!r} is not allowed: earliest or latest")
    device = trajectory.device
    episodes, count = trajectory.shape[0], candidates.numel()
    spacing = int(candidates[1] - candidates[0]) if count > 1 else 1
    # The kept candidate per episode: index into the grid (earliest = smallest, latest = largest).
    sentinel = count if keep == "earliest" else -1
    best = torch.full((episodes,), sentinel, dtype=torch.long, device=device)
    arrival = torch.zeros(episodes, count, dtype=torch.long, device=device)
    aircraft = start_rows["aircraft_state"]
    record = SearchRecord(
        action=torch.zeros(episodes, max_decisions, dtype=torch.long, device=device),
        aircraft_state=aircraft.new_zeros(episodes, max_decisions, aircraft.shape[-1]),
        destination_state=aircraft.new_zeros(episodes, max_decisions, start_rows["destination_state"].shape[-1]),
        baseline_log_prob=aircraft.new_zeros(episodes, max_decisions),
    )
    wave_search = _WaveSearch(start_rows, trajectory, motion, candidates, keep, baseline, simulator, max_decisions,
                              spacing, best, arrival, record, targets)
    pending = torch.arange(episodes, device=device)
    for wave in candidate_waves(count, keep):
        if pending.numel() == 0:
            break
        wave_search.run(pending, wave.to(device))
        pending = pending[best[pending] == sentinel]
    found = (best >= 0) & (best < count)
    winner_index = torch.where(found, best, -1)
    winner_arrival = arrival.gather(1, winner_index.clamp(min=0)[:, None]).squeeze(1)
    return SearchResult(torch.where(found, winner_arrival, 0), winner_index, record)


@dataclass(frozen=True)
class _WaveSearch:
    """The search's state shared by its waves (``best``, ``arrival`` and ``record`` are updated in place)."""

    start_rows: TensorDictBase
    trajectory: torch.Tensor
    motion: torch.Tensor
    candidates: torch.Tensor
    keep: str
    baseline: BaselinePolicy
    simulator: Simulator
    budget: int
    spacing: int
    best: torch.Tensor
    arrival: torch.Tensor
    record: SearchRecord
    targets: TargetActionTable | None

    def run(self, pending: torch.Tensor, wave: torch.Tensor) -> None:
        """One time loop over the rows ``(episode, candidate)`` of the ``pending`` episodes and the ``wave``'s
        candidates; updates ``best`` and ``arrival`` in place, and copies the rollout of each episode's kept
        candidate (when this wave holds it) into ``record``.

        The loop works on plain tensors: B's observation and mode, the simulator, the end checks. The rest of
        the environment's transition (reward, observation of the real destination) is computed afterwards for
        the kept rollouts only (:mod:`agrl.rl.reuse.completion`).
        """
        start_rows, motion, best, arrival, budget = self.start_rows, self.motion, self.best, self.arrival, self.budget
        device = self.trajectory.device
        size = wave.numel()
        episode = pending.repeat_interleave(size)
        candidate = wave.repeat(pending.numel())
        target_step = self.candidates[candidate]
        # Steps each row may run: to its candidate's limit, or to the end of the episode's decision budget.
        stop = torch.minimum((target_step + self.spacing).clamp(max=budget), budget - start_rows["step_count"][episode])
        steps = int(stop.max())
        predicted = self.trajectory[episode, target_step]
        aircraft = start_rows["aircraft_state"][episode]
        destination = start_rows["destination_state"][episode]
        # What B reads beside the state: the maneuver flown, or the targets held.
        memory = (start_rows["last_action"][episode].long() if self.targets is None
                  else start_rows["held_targets"][episode])
        reduce = "amin" if self.keep == "earliest" else "amax"
        # The running rows, compacted as rows end: their row number, episode, candidate, prediction and stop.
        alive = torch.arange(episode.numel(), device=device)
        log = []  # per step: the running rows, B's actions and the simulator's states after the step
        for step in range(steps):
            if alive.numel() == 0:
                break
            action, log_prob = self.baseline.mode_and_log_prob(
                self.baseline.observation(aircraft, predicted, memory))
            if self.targets is None:
                result = _simulate(self.simulator, aircraft, destination, motion[episode, step, 0],
                                   motion[episode, step, 1], action)
                memory_after = action
            else:
                held, _ = apply_target_action(HeldTargets(*memory.unbind(-1)), action, self.targets)
                memory_after = torch.stack(tuple(held), dim=-1)
                result = _simulate(self.simulator.fly_targets, aircraft, destination, motion[episode, step, 0],
                                   motion[episode, step, 1], memory_after)
            log.append((alive, action, result.aircraft_state, result.destination_state, log_prob))
            success = result.outcome == Outcome.SUCCESS
            if bool(success.any()):
                arrival[episode[success], candidate[success]] = step + 1
                best.scatter_reduce_(0, episode[success], candidate[success], reduce=reduce)
            # Still running: not ended by the simulator (success, airspace), the budget, or the candidate's limit;
            # and not on the far side of its episode's kept success (it can no longer be the one kept).
            running = (result.outcome == Outcome.RUNNING) & (step + 1 < stop)
            running &= candidate < best[episode] if self.keep == "earliest" else candidate > best[episode]
            aircraft, destination, memory = result.aircraft_state, result.destination_state, memory_after
            if bool(running.all()):
                continue
            keep = running.nonzero().squeeze(-1)
            alive, episode, candidate, predicted, stop = (
                field[keep] for field in (alive, episode, candidate, predicted, stop))
            aircraft, destination, memory = aircraft[keep], destination[keep], memory[keep]
        if log:
            self._record(pending, wave, log)

    def _record(self, pending: torch.Tensor, wave: torch.Tensor, log: list) -> None:
        """Copy the logged rollout of each episode whose kept candidate is in ``wave`` into ``record``."""
        best, record = self.best, self.record
        device = self.trajectory.device
        size = wave.numel()
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
    simulator: Simulator, aircraft: torch.Tensor, destination: torch.Tensor, destination_speed: torch.Tensor,
    destination_turn_rate: torch.Tensor, control: torch.Tensor,
) -> DecisionResult:
    """The environment's simulator (as in ``env.transition``; ``control``: the maneuver, or the held targets for
    ``fly_targets``), with a single row doubled: a batch of one would make the fused simulator recompile
    (torch.compile specialises sizes 0 and 1), a 10-20 s stall in the middle of training."""
    if aircraft.shape[0] != 1:
        return simulator(aircraft, destination, destination_speed, destination_turn_rate, control)
    doubled = simulator(aircraft.repeat(2, 1), destination.repeat(2, 1), destination_speed.repeat(2),
                        destination_turn_rate.repeat(2), control.repeat(2, *([1] * (control.dim() - 1))))
    return DecisionResult(*(field[:1] for field in doubled))
