"""Evaluation as the paper does it (section 5): many episodes with the deterministic policy.

Metrics (Table 3): success rate (with a 95 % Wilson interval), the average number
of instructions per episode and the time to produce one instruction. An
*instruction* is a decision whose maneuver differs from the one being flown (the
aircraft starts in steady flight), i.e. what a controller would have to say;
*decisions* counts every 3 s decision, including "keep flying as you are".
"""

from __future__ import annotations

import csv
import json
import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import torch
from tensordict import TensorDictBase
from torchrl.envs import ExplorationType, set_exploration_type

from agrl.core.compiled import WHOLE_VECTOR_ROWS, padded_rows
from agrl.core.termination import Outcome
from agrl.envs.guidance import GuidanceEnv
from agrl.rl.models import CategoricalSampler, logits_network


@dataclass
class EpisodeRecords:
    """One row per episode; ``trajectory_*`` are ``(traced episodes, steps + 1, ...)`` when recorded (the first
    episodes' paths, :func:`run_episodes`' ``trajectories``)."""

    initial_aircraft_state: torch.Tensor
    outcome: torch.Tensor
    decisions: torch.Tensor
    instructions: torch.Tensor
    episode_return: torch.Tensor
    final_distance: torch.Tensor
    trajectory_aircraft: torch.Tensor | None = None
    trajectory_destination: torch.Tensor | None = None


#: What :func:`run_episodes` keeps of each row at the end of its episode; the env counts decisions, instructions and
#: return.
_FINAL_KEYS = ("aircraft_state", "destination_state", "outcome", "step_count", "instruction_count", "episode_return")


@torch.no_grad()
def run_episodes(
    env: GuidanceEnv, actor, trajectories: int = 0, reset: TensorDictBase | None = None
) -> EpisodeRecords:
    """Run one episode per env row with the actor's deterministic (argmax) action (a categorical actor of
    :func:`~agrl.rl.models.make_actor` steps as its :class:`~agrl.rl.models.CategoricalSampler`: the same actions).

    Each decision steps only the rows still flying (:meth:`GuidanceEnv.transition`, padded to whole vectors by
    :func:`agrl.core.compiled.padded_rows`), so an evaluation costs its episodes' decisions rather than its longest
    episode's times its rows; the irregular destination's redraws still come from the env's generator for every
    row, as the env's own step draws them. The episodes are those of ``env.step`` on the whole batch, bit for bit
    where that batch fills whole vectors. ``trajectories``: how many episodes (the first rows) also keep their path,
    state by state (what a trajectory figure draws; every path of
    a large evaluation would cost hundreds of megabytes).
    """
    if trajectories < 0:
        raise ValueError(f"trajectories={trajectories} is not allowed: an integer >= 0 (episodes whose paths are kept)")
    td = env.reset(reset) if reset is not None else env.reset()
    count = env.batch_size.numel()
    traced = min(trajectories, count)
    initial = td["aircraft_state"].clone()
    final = td.select(*_FINAL_KEYS).clone()
    aircraft_now, destination_now = td["aircraft_state"][:traced].clone(), td["destination_state"][:traced].clone()
    aircraft_path, destination_path = [aircraft_now.clone()], [destination_now.clone()]
    # Every row's destination motion, redrawn each decision as env.step would (finished rows' values unused).
    speed, turn_rate = td["destination_speed"], td["destination_turn_rate"]
    rows = torch.arange(count, device=env.device)  # the env rows still flying, in order
    state = td
    policy = CategoricalSampler(actor) if logits_network(actor) is not None else actor
    with set_exploration_type(ExplorationType.DETERMINISTIC):
        for _ in range(env.params.max_decisions):
            state = policy(state)
            speed, turn_rate = env.next_destination_motion(speed, turn_rate)
            step = _aligned_transition(env, state, speed[rows], turn_rate[rows])
            if traced:
                shown = rows < traced
                aircraft_now[rows[shown]] = step["aircraft_state"][shown]
                destination_now[rows[shown]] = step["destination_state"][shown]
                aircraft_path.append(aircraft_now.clone())
                destination_path.append(destination_now.clone())
            done = step["done"].squeeze(-1)
            if bool(done.any()):
                final[rows[done]] = step[done].select(*_FINAL_KEYS)
                flying = ~done
                rows, step = rows[flying], step[flying]
                if not rows.numel():
                    break
            state = step
    relative = final["aircraft_state"][:, :2] - final["destination_state"][:, :2]
    return EpisodeRecords(
        initial_aircraft_state=initial.cpu(),
        outcome=final["outcome"].cpu(),
        decisions=final["step_count"].cpu(),
        instructions=final["instruction_count"].cpu(),
        episode_return=final["episode_return"].cpu(),
        final_distance=relative.norm(dim=-1).cpu(),
        trajectory_aircraft=torch.stack(aircraft_path, 1).cpu() if traced else None,
        trajectory_destination=torch.stack(destination_path, 1).cpu() if traced else None,
    )


def _aligned_transition(env: GuidanceEnv, state: TensorDictBase, speed: torch.Tensor,
                        turn_rate: torch.Tensor) -> TensorDictBase:
    """``env.transition`` of ``state``'s rows, run on whole vectors (:func:`agrl.core.compiled.padded_rows`: copies
    of the first row fill the batch up) so that each row is computed as in any other batch."""
    rows = state.shape[0]
    if not rows % WHOLE_VECTOR_ROWS:
        return env.transition(state, speed, turn_rate)
    index = padded_rows(torch.arange(rows, device=speed.device))
    return env.transition(state[index], speed[index], turn_rate[index])[:rows]


def wilson_interval(successes: int, trials: int, z: float = 1.959964) -> tuple[float, float]:
    """95 % Wilson score interval of a binomial proportion."""
    if trials == 0:
        return 0.0, 1.0
    p = successes / trials
    denominator = 1 + z * z / trials
    centre = (p + z * z / (2 * trials)) / denominator
    half = z * math.sqrt(p * (1 - p) / trials + z * z / (4 * trials * trials)) / denominator
    # No success (no failure) puts that end at exactly 0 (1): the formula's two terms are then equal, and their
    # difference would be a rounding residue (2e-19), not a bound.
    low = 0.0 if successes == 0 else max(0.0, centre - half)
    high = 1.0 if successes == trials else min(1.0, centre + half)
    return low, high


def summarise(records: EpisodeRecords) -> dict[str, float | int | dict]:
    """Table-3 style summary of :func:`run_episodes`' records."""
    episodes = int(records.outcome.numel())
    success = records.outcome == Outcome.SUCCESS
    successes = int(success.sum())
    low, high = wilson_interval(successes, episodes)

    def mean(values: torch.Tensor, mask: torch.Tensor | None = None) -> float | None:
        # None (JSON null) when there is nothing to average, e.g. no successful episode.
        values = values.float() if mask is None else values[mask].float()
        return float(values.mean()) if values.numel() else None

    return {
        "episodes": episodes,
        "success_rate": successes / episodes,
        "success_rate_ci95": [low, high],
        "instructions_per_episode": mean(records.instructions),
        "instructions_per_successful_episode": mean(records.instructions, success),
        "decisions_per_episode": mean(records.decisions),
        "decisions_per_successful_episode": mean(records.decisions, success),
        "mean_return": mean(records.episode_return),
        "outcomes": {
            outcome.name.lower(): int((records.outcome == outcome).sum())
            for outcome in Outcome
            if outcome is not Outcome.RUNNING
        },
    }


def search_objective(summary: dict[str, Any], success: float, max_instructions: float,
                     penalty_seconds: float) -> float:
    """A recipe's cost to a sweeper (the ``search`` config): its seconds of training if the final evaluation's
    ``summary`` has at least ``success`` and at most ``max_instructions`` per episode; else those seconds plus
    ``penalty_seconds`` per percentage point of success short and per instruction over, so that a search is led
    towards the target rather than to the shortest run."""
    short = max(0.0, success - summary["success_rate"]) * 100
    over = max(0.0, summary["instructions_per_episode"] - max_instructions)
    return summary["training_wall_time_s"] + penalty_seconds * (short + over)


@torch.no_grad()
def instruction_latency_ms(env: GuidanceEnv, actor, queries: int = 200) -> float:
    """Median wall time (ms) to produce one instruction for one aircraft: observation + policy.

    Like the paper's "average computational time" (Table 3), for a single query.
    """
    td = env.reset()[:1].clone()
    timings = []
    with set_exploration_type(ExplorationType.DETERMINISTIC):
        for _ in range(queries + 10):
            start = time.perf_counter()
            td["observation"] = env.observe(td)
            actor(td)
            timings.append(time.perf_counter() - start)
    timings = sorted(timings[10:])
    return 1000.0 * timings[len(timings) // 2]


def write_evaluation(directory: Path, summary: dict[str, Any], records) -> None:
    """``eval.json`` (summary) and ``episodes.csv`` (one row per episode)."""
    directory.mkdir(parents=True, exist_ok=True)
    (directory / "eval.json").write_text(json.dumps(summary, indent=2) + "\n")
    with (directory / "episodes.csv").open("w", newline="") as file:
        writer = csv.writer(file)
        writer.writerow(["episode", "x0_m", "y0_m", "z0_m", "outcome", "decisions", "instructions", "return",
                         "final_distance_m"])
        for index in range(records.outcome.numel()):
            x0, y0, z0 = records.initial_aircraft_state[index, :3].tolist()
            writer.writerow([index, round(x0, 1), round(y0, 1), round(z0, 1),
                             Outcome(int(records.outcome[index])).name.lower(), int(records.decisions[index]),
                             int(records.instructions[index]), round(float(records.episode_return[index]), 4),
                             round(float(records.final_distance[index]), 1)])
