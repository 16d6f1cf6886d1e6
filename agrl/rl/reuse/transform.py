"""The replay-buffer transform that wires policy reuse's jobs together (the paper's Algorithm 1).

When collected data is added to the replay buffer (``rb.extend`` calls :meth:`PolicyReuseTransform.inv`), the
transform joins the batch to the rows kept from earlier batches (:mod:`~agrl.rl.reuse.carry`), selects each new
episode with probability ``e`` (lines 10-13; ``e`` drops by ``k`` per selected episode, floored at 0, line 32),
predicts the selected episodes' destination (:mod:`~agrl.rl.reuse.prediction`), searches their candidate
termination steps with the frozen baseline B (:mod:`~agrl.rl.reuse.search`) and replaces the episodes with a
success by their completed re-played transitions (:mod:`~agrl.rl.reuse.completion`). It never writes into its
input; sampling returns stored rows unchanged.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import torch
from tensordict import TensorDictBase
from torchrl.envs import Transform

from agrl.envs.guidance import GuidanceEnv
from agrl.rl.reuse.carry import EpisodeCarrier, searchable_episodes
from agrl.rl.reuse.completion import fitting_episodes, relabelled_rows, relabelled_trajectories, stored_rows
from agrl.rl.reuse.prediction import BaselinePolicy, destination_prediction
from agrl.rl.reuse.search import SearchRecord, candidate_steps, search_candidates


class PolicyReuseTransform(Transform):
    """Rewrites collected episodes with a frozen baseline actor (Algorithm 1; ``docs/policy_reuse.md``).

    ``baseline_actor``: B (frozen here: ``eval()``, no gradients), reading ``baseline_observation``
    (``relative`` or ``absolute``); ``env``: the collecting environment (its simulator, transition and envs);
    ``ppo_targets(trajectories, valid)``: PPO's quantities for the re-played trajectories (in the trainer,
    :func:`~agrl.rl.reuse.completion.relabelled_ppo_targets`). Algorithm 1's knobs: ``initial_selection_factor``
    (e), ``selection_decay`` (k), the candidate grid (``candidate_stride``, ``max_candidates``:
    :func:`~agrl.rl.reuse.search.candidate_steps`) and ``keep`` (``earliest`` or ``latest`` successful t_n).
    ``max_rows``: the buffer's size (None: uncut); ``seed``: the selection draws'. ``relabel_unfinished=False``
    and ``relabel_own_successes=False`` are this project's shortcuts (not Algorithm 1): they skip the search of
    an episode still running at the batch's end, or of one the agent itself flew to a success.
    """

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
        self.baseline = BaselinePolicy(self.baseline_actor, env.params.simulation, baseline_observation,
                                       holds_targets=env.holds_targets)
        self.env = env
        self.selection_factor = float(initial_selection_factor)
        self.selection_decay = float(selection_decay)
        self.keep = keep
        self.ppo_targets = ppo_targets
        self.max_rows = max_rows
        self.relabel_unfinished = relabel_unfinished
        self.relabel_own_successes = relabel_own_successes
        self.candidates = candidate_steps(env.params.max_decisions, candidate_stride, max_candidates).to(env.device)
        self.generator = torch.Generator(device=env.device).manual_seed(seed + 7_919)
        # Rows of each env's unfinished episode (since its start), kept for the next batch.
        self.carrier = EpisodeCarrier(env.batch_size.numel(), env.device)
        self._statistics: dict[str, float] = {}

    # ------------------------------------------------------------------ state for checkpoints
    def state_dict(self, *args, **kwargs) -> dict:
        """e, the selection generator's state and the kept rows (``carry``), as plain tensors and dicts
        (checkpoints are read with ``torch.load(weights_only=True)``)."""
        state = {"selection_factor": self.selection_factor, "generator": self.generator.get_state()}
        carry = self.carrier.state_dict()
        if carry is not None:
            state["carry"] = carry
        return state

    def load_state_dict(self, state: dict, *args, **kwargs) -> None:
        """Restore what :meth:`state_dict` returned (without ``carry``: no rows kept)."""
        self.selection_factor = float(state["selection_factor"])
        self.generator.set_state(state["generator"])
        self.carrier.load_state_dict(state.get("carry"))

    def last_statistics(self) -> dict[str, float]:
        """Dashboard scalars of the last call (``train/reuse_fraction``, ``train/e``, ...)."""
        return dict(self._statistics)

    # ------------------------------------------------------------------ Transform API
    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        """Sampling returns stored rows unchanged."""
        return tensordict

    def _call(self, tensordict: TensorDictBase) -> TensorDictBase:
        return tensordict

    @torch.no_grad()
    def _inv_call(self, tensordict: TensorDictBase) -> TensorDictBase:
        return self.relabel(tensordict)

    # ------------------------------------------------------------------ Algorithm 1
    @torch.no_grad()
    def relabel(self, rows: TensorDictBase) -> TensorDictBase:
        """Flat collector rows ``(envs x steps,)`` -> what the buffer stores: the own rows (``PPO_KEYS``) of the
        untouched episodes, in the collector's order, then the re-played rows of the relabelled ones, cut at
        ``max_rows``. Sets :meth:`last_statistics`."""
        start_time = time.perf_counter()
        device = rows.device
        if rows.batch_dims != 1:
            raise ValueError(f"PolicyReuseTransform expects flat rows (one batch dimension), got {rows.batch_size}")
        # Each env's rows since its episode's start: the rows kept from earlier batches, then this batch's.
        known = self.carrier.join(rows)
        episode_ids = known.episode_ids
        traj_ids = episode_ids[known.in_batch]  # the episode of every row of this batch
        starts = known.starts()
        new = known.in_batch[starts]
        # Episodes starting in this batch, each selected with probability e (line 10-11); an episode carried
        # over from an earlier batch keeps the choice made when it started.
        selected = torch.zeros(starts.numel(), dtype=torch.bool, device=device)
        draws = torch.rand(int(new.sum()), generator=self.generator, device=device) < self.selection_factor
        selected[new] = draws
        selected[~new] = known.carried[starts[~new]]
        self.carrier.keep(known, starts, selected)
        # The share of this batch's rows whose episode's start is known: the rows that can be relabelled.
        has_start = torch.zeros(int(episode_ids[-1]) + 1, dtype=torch.bool, device=device)
        has_start[episode_ids[starts]] = True
        relabellable = float(has_start[traj_ids].float().mean())
        searched = selected & searchable_episodes(known, rows, starts, relabel_unfinished=self.relabel_unfinished,
                                                  relabel_own_successes=self.relabel_own_successes)
        starts = starts[searched]
        episodes = int(starts.numel())
        self.selection_factor = max(0.0, self.selection_factor - self.selection_decay * int(draws.sum()))

        relabelled = None
        succeeded = torch.zeros(episodes, dtype=torch.bool, device=device)
        dropped = torch.zeros_like(succeeded)
        if episodes:
            trajectory, motion = destination_prediction(known.rows, starts, episode_ids, self.env.params)
            start_rows = known.rows[starts]
            result = search_candidates(start_rows, trajectory, motion, candidates=self.candidates, keep=self.keep,
                                       baseline=self.baseline, simulator=self.env.simulator,
                                       max_decisions=self.env.params.max_decisions, targets=self.env.target_table)
            found, dropped = fitting_episodes(result.index >= 0, result.arrival, traj_ids, episode_ids[starts],
                                              rows.numel(), self.max_rows)
            succeeded |= dropped  # found, but their rows would fall past max_rows: neither own nor re-played
            if found.numel():
                kept = SearchRecord(*(field[found] for field in result.record))
                trajectories, valid = relabelled_trajectories(start_rows[found], motion[found],
                                                              result.arrival[found], kept, self.env)
                relabelled = relabelled_rows(trajectories, valid, self.ppo_targets)
                succeeded[found] = True
        replaced_ids = episode_ids[starts[succeeded]]
        output = stored_rows(rows, ~torch.isin(traj_ids, replaced_ids), relabelled, self.max_rows)
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
