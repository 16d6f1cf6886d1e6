"""Policy reuse by destination position prediction (the paper's Algorithm 1) as a replay-buffer transform.

When collected data is added to the replay buffer, each episode with rows in the batch whose start is known
(in this batch, or kept from an earlier one) is, if it was selected with probability ``e`` when it started,
re-played with the frozen baseline agent B. The jobs, one module each:

- :mod:`~agrl.rl.reuse.carry`: each env's rows since its running episode's start, kept from one collector batch to
  the next (:class:`EpisodeCarrier`), and which episodes are searched (:func:`searchable_episodes`).
- :mod:`~agrl.rl.reuse.prediction`: the destination's trajectory, recorded in the batch and extended past the
  episode's end by its motion model (:func:`destination_prediction`, equation 19), and B's deterministic action and
  log-probability on the state whose destination fields are a predicted one (:class:`BaselinePolicy`, eq. 20).
- :mod:`~agrl.rl.reuse.search`: for every candidate termination step t_n (:func:`candidate_steps`) the aircraft is
  re-simulated from the episode's start, B steered by the destination's state at t_n, each step the real
  environment's transition; the earliest (``keep="earliest"``) or latest successful t_n is kept
  (:func:`search_candidates`, in waves: :func:`candidate_waves`), its rollout recorded (:class:`SearchRecord`).
- :mod:`~agrl.rl.reuse.completion`: the kept rollouts as the environment's full transitions with the real
  destination (:func:`relabelled_trajectories`), PPO's targets for them (:func:`relabelled_ppo_targets`) and the
  rows the buffer stores (:func:`stored_rows`); if no candidate succeeds the agent's own data is kept.
- :mod:`~agrl.rl.reuse.transform`: :class:`PolicyReuseTransform`, the TorchRL transform wiring them, with the
  selection factor ``e`` (drops by ``k`` per selected episode, floored at 0), statistics and checkpoint state.

Two shortcuts, off by default (``relabel_unfinished=False``, ``relabel_own_successes=False``), skip the search
of an episode still running at the batch's end (it is searched once, in the batch where it ends: Algorithm 1
line 6 searches after Z ran the complete episode) or of one Z itself flew to a success; their rows stay Z's.
``docs/policy_reuse.md`` describes the method and its measurements.
"""

from agrl.rl.reuse.carry import CARRY_KEYS, TRAJECTORY_KEY, EpisodeCarrier, KnownRows, searchable_episodes
from agrl.rl.reuse.completion import (
    PPO_KEYS,
    fitting_episodes,
    relabelled_ppo_targets,
    relabelled_rows,
    relabelled_trajectories,
    stored_rows,
)
from agrl.rl.reuse.prediction import BaselinePolicy, destination_prediction
from agrl.rl.reuse.search import (
    SearchRecord,
    SearchResult,
    candidate_steps,
    candidate_waves,
    search_candidates,
)
from agrl.rl.reuse.transform import PolicyReuseTransform

__all__ = [
    "CARRY_KEYS", "PPO_KEYS", "TRAJECTORY_KEY", "BaselinePolicy", "EpisodeCarrier", "KnownRows",
    "PolicyReuseTransform", "SearchRecord", "SearchResult", "candidate_steps", "candidate_waves",
    "destination_prediction", "fitting_episodes", "relabelled_ppo_targets", "relabelled_rows",
    "relabelled_trajectories", "search_candidates", "searchable_episodes", "stored_rows",
]
