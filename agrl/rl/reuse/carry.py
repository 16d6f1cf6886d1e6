"""Episodes across collector batches: each env's rows since its running episode's start, kept for the next batch.

Algorithm 1 re-plays an episode from its start S_0. A collector batch cuts episodes at its end, so the transform
keeps, for every env, the rows of its unfinished episode (since the episode's start) and puts them in front of
that env's rows of the next batch, when that batch continues them. :class:`EpisodeCarrier` holds those rows;
its :meth:`~EpisodeCarrier.state_dict` is plain tensors, so a resumed run continues exactly.

Layout: the collector's flat batch is env after env (``envs x steps`` rows); an episode is a contiguous run of one
env's rows that begins at ``step_count == 0`` (or at the env's first known row).
"""

from __future__ import annotations

from typing import NamedTuple

import torch
from tensordict import TensorDict, TensorDictBase

from agrl.core.termination import Outcome
from agrl.envs.guidance import HELD_TARGETS_KEY, STATE_KEYS

#: The collector's episode id of each row (one id per episode and env, ascending within an env).
TRAJECTORY_KEY = ("collector", "traj_ids")
#: Entries of the rows kept from one batch to the next (what the search and the prediction read).
CARRY_KEYS = (*STATE_KEYS, *[("next", key) for key in ("aircraft_state", "destination_state", "destination_speed",
                                                      "destination_turn_rate", "done")])


class KnownRows(NamedTuple):
    """A batch's rows with, in front of each env's, the rows kept from its episode's earlier batches.

    All per-row fields have one entry per known row ``(N,)``, env after env.
    """

    rows: TensorDictBase  #: the known rows (``CARRY_KEYS``), ``(N,)``
    per_env: torch.Tensor  #: ``(envs,)`` long: known rows per env (kept rows + this batch's steps)
    in_batch: torch.Tensor  #: ``(N,)`` bool: the row is from this batch (not kept from an earlier one)
    episode_ids: torch.Tensor  #: ``(N,)`` long, ascending from 0: the episode of each row (contiguous runs)
    carried: torch.Tensor  #: ``(N,)`` bool: a kept row whose episode was selected when it started

    def starts(self) -> torch.Tensor:
        """``(S,)`` long: the index of every episode start (``step_count == 0``) among the known rows, ascending."""
        return (self.rows["step_count"] == 0).nonzero().squeeze(-1)


class EpisodeCarrier:
    """Keeps each env's unfinished episode (its rows since the start) from one collector batch to the next.

    :meth:`join` puts the kept rows in front of a new batch's; :meth:`keep` stores the rows to carry after it.
    After :meth:`keep`, ``rows`` holds the kept rows (flat, env after env), ``lengths`` ``(envs,)`` their count
    per env (each ``< max_decisions``: an episode ends at its decision budget) and ``selected`` ``(envs,)``
    whether that env's kept episode was selected when it started. All three are None before the first
    :meth:`keep` (and after loading a state without kept rows).
    """

    def __init__(self, envs: int, device: torch.device | str):
        self.envs = int(envs)
        self.device = torch.device(device)
        self.rows: TensorDictBase | None = None
        self.lengths: torch.Tensor | None = None
        self.selected: torch.Tensor | None = None

    def join(self, batch: TensorDictBase) -> KnownRows:
        """``batch`` (flat collector rows, ``envs x steps``) with each env's kept rows in front of its own.

        Kept rows are used only when the batch continues them (the next step count and the same aircraft state).
        """
        device = batch.device
        envs = self.envs
        if batch.numel() % envs:
            raise ValueError(f"PolicyReuseTransform expects {envs} envs x steps rows, got {batch.numel()} rows")
        steps = batch.numel() // envs
        batch = batch.select(*CARRY_KEYS, HELD_TARGETS_KEY, strict=False)  # held targets: an agent holding them
        first = torch.arange(envs, device=device) * steps
        lengths = torch.zeros(envs, dtype=torch.long, device=device)
        if self.rows is not None and self.lengths.numel() == envs:
            end = torch.cumsum(self.lengths, 0) - 1
            # (batch_size.numel(): a TensorDict's numel() is 1 when it holds no rows)
            last = self.rows[end.clamp(min=0)] if self.rows.batch_size.numel() else None
            if last is not None:
                continues = (
                    (self.lengths > 0)
                    & (batch["step_count"][first] == last["step_count"] + 1)
                    & (batch["aircraft_state"][first] == last["next", "aircraft_state"]).all(-1)
                )
                lengths = torch.where(continues, self.lengths, 0)
        carry_rows = self.rows.numel() if self.rows is not None and lengths.any() else 0
        source = torch.cat([self.rows, batch]) if carry_rows else batch
        offset = torch.cumsum(self.lengths, 0) - self.lengths if carry_rows else lengths
        per_env = lengths + steps
        env = torch.repeat_interleave(torch.arange(envs, device=device), per_env)
        position = torch.arange(int(per_env.sum()), device=device) - (torch.cumsum(per_env, 0) - per_env)[env]
        kept = position < lengths[env]
        index = torch.where(kept, offset[env] + position, carry_rows + env * steps + position - lengths[env])
        known = source[index]
        boundary = (known["step_count"] == 0) | (position == 0)
        episode_ids = torch.cumsum(boundary.long(), 0) - 1
        carried = kept & self.selected[env] if carry_rows else kept
        return KnownRows(known, per_env, ~kept, episode_ids, carried)

    def keep(self, known: KnownRows, starts: torch.Tensor, selected: torch.Tensor) -> None:
        """Keep the rows of each env's last episode for the next batch, if it has not ended and its start is known.

        ``starts`` ``(S,)``: :meth:`KnownRows.starts`; ``selected`` ``(S,)`` bool: whether each of those episodes
        was selected. At most ``max_decisions - 1`` rows per env: an episode ends at its decision budget.
        """
        rows, per_env = known.rows, known.per_env
        device = rows.device
        last_rows = torch.cumsum(per_env, 0) - 1
        first_rows = last_rows - per_env + 1
        # Each env's last start (starts ascend, envs are contiguous): the start just before its last row.
        position = torch.searchsorted(starts, last_rows, right=True) - 1
        padded = torch.cat([starts, starts.new_full((1,), -1)])  # index -1: no start in the rows at all
        last_start = torch.where(position >= 0, padded[position], -1)
        unfinished = ~rows["next", "done"].reshape(-1)[last_rows] & (last_start >= first_rows)
        lengths = torch.where(unfinished, last_rows - last_start + 1, 0)
        env = torch.repeat_interleave(torch.arange(per_env.numel(), device=device), lengths)
        offset = torch.arange(int(lengths.sum()), device=device) - (torch.cumsum(lengths, 0) - lengths)[env]
        self.rows = rows[last_start[env] + offset].clone()
        self.lengths = lengths
        self.selected = unfinished & torch.cat([selected, selected.new_zeros(1)])[position]

    def state_dict(self) -> dict | None:
        """The kept rows as plain tensors (``{"rows": dict, "lengths", "selected"}``), or None if none are kept."""
        if self.rows is None:
            return None
        return {"rows": self.rows.to_dict(), "lengths": self.lengths.clone(), "selected": self.selected.clone()}

    def load_state_dict(self, state: dict | None) -> None:
        """Restore what :meth:`state_dict` returned (None: nothing kept), on this carrier's device."""
        if state is None:
            self.rows = self.lengths = self.selected = None
            return
        lengths = state["lengths"].to(self.device)
        self.rows = TensorDict(state["rows"], batch_size=[int(lengths.sum())], device=self.device)
        self.lengths, self.selected = lengths, state["selected"].to(self.device)


def searchable_episodes(
    known: KnownRows, batch: TensorDictBase, starts: torch.Tensor, *, relabel_unfinished: bool,
    relabel_own_successes: bool,
) -> torch.Tensor:
    """``(S,)`` bool per episode start of ``known``: whether its search runs.

    All True unless a shortcut is off: ``relabel_unfinished=False`` skips episodes still running at the batch's
    end, ``relabel_own_successes=False`` episodes the agent flew to a success (``batch``'s ``("next", "outcome")``).
    """
    searchable = torch.ones(starts.numel(), dtype=torch.bool, device=starts.device)
    if relabel_unfinished and relabel_own_successes:
        return searchable
    rows, episode_ids = known.rows, known.episode_ids
    # Each episode's last row (episode ids ascend, one contiguous run of rows each).
    last_row = torch.searchsorted(episode_ids, episode_ids[starts], right=True) - 1
    ended = rows["next", "done"].reshape(-1)[last_row]
    if not relabel_unfinished:
        searchable &= ended
    if not relabel_own_successes:
        # An ended episode's last row is in this batch (kept rows are those of unfinished episodes).
        outcome = torch.full((rows.numel(),), int(Outcome.RUNNING), dtype=torch.long, device=starts.device)
        outcome[known.in_batch] = batch["next", "outcome"].reshape(-1).long()
        searchable &= ~(ended & (outcome[last_row] == Outcome.SUCCESS))
    return searchable
