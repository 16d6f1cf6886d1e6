"""Completing the kept re-played episodes into what the replay buffer stores (Algorithm 1, lines 23-31).

The search recorded, per step of each kept rollout, B's action, the simulator's result and B's log-probability.
:func:`relabelled_trajectories` completes them into the environment's full transitions (the real destination,
its rewards and done flags), :func:`relabelled_ppo_targets` adds what PPO needs for actions that are B's, and
:func:`stored_rows` assembles the buffer's rows: the agent's own rows of the untouched episodes, then the
re-played ones, cut at the buffer's size (:func:`fitting_episodes` skips completing episodes past that cut).
"""

from __future__ import annotations

from collections.abc import Callable

import torch
from tensordict import TensorDict, TensorDictBase
from torchrl.modules import ProbabilisticActor

from agrl.core.autopilot import HeldTargets, apply_target_action
from agrl.core.simulation import DecisionResult
from agrl.core.termination import Outcome
from agrl.envs.guidance import GuidanceEnv
from agrl.rl.reuse.search import SearchRecord

#: Entries kept in the buffer for PPO when the transform is active.
PPO_KEYS = ("observation", "action", "action_log_prob", "state_value", "advantage", "value_target", "relabelled")


def fitting_episodes(
    found: torch.Tensor, arrival: torch.Tensor, traj_ids: torch.Tensor, episode_ids: torch.Tensor, rows: int,
    max_rows: int | None,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Which found episodes to re-play: those whose re-played rows will be inside ``max_rows``.

    ``found`` ``(E,)`` bool: the searched episodes with a success; ``arrival`` ``(E,)``: their re-played lengths
    (decisions); ``traj_ids`` ``(rows,)``: the episode id of each of the batch's ``rows`` rows; ``episode_ids``
    ``(E,)``: each searched episode's id. The output is the kept own rows, then the re-played episodes in order,
    cut at ``max_rows`` (None: no cut). Completing an episode whose rows all fall past the cut is wasted work
    (early in training, when the agent's episodes are short, a large part of it), so those are not completed.
    Returns the indices ``(F,)`` to re-play and an ``(E,)`` mask of the found episodes that are dropped (they
    would have been cut anyway).
    """
    index = found.nonzero().squeeze(-1)
    dropped = torch.zeros_like(found)
    if max_rows is None or index.numel() == 0:
        return index, dropped
    ids, counts = torch.unique(traj_ids, return_counts=True)  # sorted ids
    own_kept = rows - int(counts[torch.searchsorted(ids, episode_ids[index])].sum())
    first_row = own_kept + torch.cumsum(arrival[index], 0) - arrival[index]
    fits = first_row < max_rows
    dropped[index[~fits]] = True
    return index[fits], dropped


def relabelled_trajectories(
    start_rows: TensorDictBase, motion: torch.Tensor, arrival: torch.Tensor, record: SearchRecord, env: GuidanceEnv,
) -> tuple[TensorDictBase, torch.Tensor]:
    """The kept candidates' episodes as the environment's full transitions, from the search's record.

    ``start_rows`` ``(E,)``: each episode's start state S_0 (the environment's state keys); ``motion``
    ``(E, max_decisions, 2)``: the destination's speed and turn rate per decision; ``arrival`` ``(E,)``: decisions
    to each kept rollout's success (>= 1); ``record``: the kept rollouts (:class:`SearchRecord`). Returns the
    trajectories ``(E, T)`` with ``T = max(arrival)`` (state keys, ``observation``, ``action``,
    ``baseline_log_prob`` and the ``next`` transition) and ``valid (E, T)``: the rows before each episode's end.

    The rest of the environment's transition (``env.complete_transition``: step count, done flags, equation-5
    reward, observation of the real destination) is computed for all episodes and steps in one batch. Every
    recorded rollout ends at its success (step ``arrival - 1``); padding after it repeats the episode's last
    transition (finite values) and is marked done and terminated, so GAE does not mix it in.
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
    held = None
    if env.holds_targets:  # the targets held before each step, and which steps changed one (instructions)
        held, changes = _held_targets(start_rows["held_targets"], actions[:, 2:], env.target_table)
        held, changes = held[row, take], changes[row, take].long()
    else:
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
    if held is not None:
        state["held_targets"] = held
    outcome = torch.where(take == (arrival - 1)[:, None], int(Outcome.SUCCESS), int(Outcome.RUNNING))
    result = DecisionResult(aircraft[row, take + 1], destination[row, take + 1], outcome)
    next_state = env.complete_transition(state, result, speed[row, take + 1], turn_rate[row, take + 1])
    # The return accumulates step by step, in the environment's order of float additions.
    reward = next_state["reward"].squeeze(-1)
    returns = [start_rows["episode_return"]]
    for step in range(length - 1):
        returns.append(returns[-1] + reward[:, step])
    state["episode_return"] = torch.stack(returns, 1)[row, take]
    next_state["episode_return"] = state["episode_return"] + reward
    state["observation"] = env.observe(state)
    # B's log-probability of its action on the observation it acted on (the destination predicted at t_n),
    # as the search computed it.
    state["baseline_log_prob"] = torch.where(valid, record.baseline_log_prob[:, :length], 0.0)
    trajectories = state.set("next", next_state)
    # Rows past an episode's end are padding: mark them terminal so GAE does not mix them in.
    trajectories["next", "done"] = trajectories["next", "done"] | ~valid[..., None]
    trajectories["next", "terminated"] = trajectories["next", "terminated"] | ~valid[..., None]
    return trajectories, valid


def _held_targets(start: torch.Tensor, actions: torch.Tensor, table) -> tuple[torch.Tensor, torch.Tensor]:
    """The targets held before each step ``(E, T, 3)`` from those at S_0 ``(E, 3)`` and the actions ``(E, T)``,
    and whether each action changed one ``(E, T)`` (:func:`agrl.core.autopilot.apply_target_action`)."""
    held, before, changed = HeldTargets(*start.unbind(-1)), [], []
    for step in range(actions.shape[1]):
        before.append(torch.stack(tuple(held), dim=-1))
        held, change = apply_target_action(held, actions[:, step], table)
        changed.append(change)
    return torch.stack(before, 1), torch.stack(changed, 1)


def relabelled_rows(
    trajectories: TensorDictBase, valid: torch.Tensor,
    ppo_targets: Callable[[TensorDictBase, torch.Tensor], TensorDictBase],
) -> TensorDictBase:
    """The valid rows of ``trajectories`` ``(E, T)`` (:func:`relabelled_trajectories`) as flat buffer rows
    ``(valid.sum(),)``, episode after episode: ``ppo_targets(trajectories, valid)`` (e.g.
    :func:`relabelled_ppo_targets`) adds PPO's quantities, and the rows keep ``PPO_KEYS`` with ``relabelled`` True.
    """
    trajectories = ppo_targets(trajectories, valid)
    flat = trajectories[valid]
    flat["relabelled"] = torch.ones(flat.batch_size, dtype=torch.bool, device=valid.device)
    return flat.select(*PPO_KEYS)


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
    along the time dimension. Sets ``action_log_prob``, ``state_value``, ``("next", "state_value")`` and what
    ``advantage`` writes (``advantage``, ``value_target``); returns ``advantage``'s output.
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


def stored_rows(
    rows: TensorDictBase, keep_own: torch.Tensor, relabelled: TensorDictBase | None, max_rows: int | None,
) -> TensorDictBase:
    """What the buffer stores: the batch's ``rows`` where ``keep_own`` ``(N,)`` (PPO's keys, ``relabelled``
    False), then the ``relabelled`` rows (None: none), the whole cut at ``max_rows`` rows (None: no cut)."""
    own = rows[keep_own].select(*[key for key in PPO_KEYS if key != "relabelled"])
    own["relabelled"] = torch.zeros(own.batch_size, dtype=torch.bool, device=rows.device)
    output = own if relabelled is None else torch.cat([own, relabelled], 0)
    if max_rows is not None and output.numel() > max_rows:
        output = output[:max_rows]  # drops the tail of the re-played rows only
    return output
