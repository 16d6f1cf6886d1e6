"""agrl.rl.evaluation: the Table-3 summary, the Wilson interval and reproducible deterministic episodes."""

from __future__ import annotations

import dataclasses
import json
import math

import pytest
import torch
from torchrl.envs import ExplorationType, set_exploration_type
from torchrl.envs.utils import step_mdp

from agrl.config import to_guidance_parameters
from agrl.core.aircraft import MANEUVER_NAMES
from agrl.core.termination import Outcome
from agrl.envs.guidance import GuidanceEnv
from agrl.rl.evaluation import (
    EpisodeRecords,
    instruction_latency_ms,
    run_episodes,
    search_objective,
    summarise,
    wilson_interval,
)
from agrl.rl.models import make_actor

pytestmark = pytest.mark.usefixtures("torch_one_thread")

Z95 = 1.959964


def records(outcomes, instructions, decisions=None, returns=None) -> EpisodeRecords:
    count = len(outcomes)
    return EpisodeRecords(
        initial_aircraft_state=torch.zeros(count, 7),
        outcome=torch.tensor([int(o) for o in outcomes]),
        decisions=torch.tensor(decisions if decisions is not None else [10] * count),
        instructions=torch.tensor(instructions),
        episode_return=torch.tensor(returns if returns is not None else [0.0] * count),
        final_distance=torch.zeros(count),
    )


# ---------------------------------------------------------------------------- summary and interval
def test_summarise_hand_made_records():
    S, A, B = Outcome.SUCCESS, Outcome.OUT_OF_AIRSPACE, Outcome.BUDGET_EXHAUSTED  # A: out of the airspace
    summary = summarise(records([S, S, A, B, S], instructions=[2, 4, 0, 6, 3], decisions=[5, 7, 20, 200, 9],
                                returns=[20.0, 18.0, -21.0, -12.0, 19.0]))
    assert summary["episodes"] == 5
    assert summary["success_rate"] == 3 / 5
    assert summary["outcomes"] == {"success": 3, "out_of_airspace": 1, "budget_exhausted": 1}
    assert summary["instructions_per_episode"] == pytest.approx(15 / 5)
    assert summary["instructions_per_successful_episode"] == pytest.approx((2 + 4 + 3) / 3)
    assert summary["decisions_per_episode"] == pytest.approx(241 / 5)
    assert summary["decisions_per_successful_episode"] == pytest.approx(21 / 3)
    assert summary["mean_return"] == pytest.approx(24.0 / 5)
    low, high = summary["success_rate_ci95"]
    assert (low, high) == wilson_interval(3, 5)
    assert low < 3 / 5 < high


def test_summarise_without_successes():
    summary = summarise(records([Outcome.OUT_OF_AIRSPACE] * 4, instructions=[1, 2, 3, 4]))
    assert summary["success_rate"] == 0.0
    assert summary["success_rate_ci95"][0] == 0.0
    # No successful episode: nothing to average, reported as None (JSON null, so eval.json stays strict JSON).
    assert summary["instructions_per_successful_episode"] is None
    assert summary["decisions_per_successful_episode"] is None
    json.dumps(summary, allow_nan=False)
    assert summary["instructions_per_episode"] == pytest.approx(2.5)


@pytest.mark.parametrize(("successes", "trials"), [(0, 10), (0, 1000), (3, 5), (50, 100), (999, 1000), (1000, 1000)])
def test_wilson_interval_properties(successes, trials):
    low, high = wilson_interval(successes, trials)
    p = successes / trials
    assert 0.0 <= low <= p <= high <= 1.0
    # Mirror symmetry: the interval of failures is the reflected interval of successes.
    mirrored = wilson_interval(trials - successes, trials)
    assert mirrored[0] == pytest.approx(1 - high) and mirrored[1] == pytest.approx(1 - low)
    assert (low == 0.0) == (successes == 0) and (high == 1.0) == (successes == trials)  # exactly, no residue
    # Wilson's score interval solves |p - q| = z sqrt(q (1 - q) / n) at both ends (where not clipped).
    for q in (low, high):
        if 0 < q < 1:
            assert abs(p - q) == pytest.approx(Z95 * math.sqrt(q * (1 - q) / trials), rel=1e-6)


def test_wilson_interval_closed_forms():
    # Zero successes: upper end z^2 / (n + z^2).
    assert wilson_interval(0, 10) == (0.0, pytest.approx(Z95**2 / (10 + Z95**2)))
    # It narrows with more trials and is symmetric about 1/2 at p = 1/2.
    low10, high10 = wilson_interval(5, 10)
    low1000, high1000 = wilson_interval(500, 1000)
    assert high1000 - low1000 < high10 - low10
    assert low10 + high10 == pytest.approx(1.0)
    assert wilson_interval(0, 0) == (0.0, 1.0)


# ---------------------------------------------------------------------------- episodes
@pytest.fixture(scope="module")
def params(compose_train, tiny_args):
    cfg = compose_train(*tiny_args({"simulation.max_decisions": 12}))
    return to_guidance_parameters(cfg.task, cfg.reward, cfg.simulation)


@pytest.fixture(scope="module")
def actor():
    torch.manual_seed(123)
    actor = make_actor([32], "tanh")
    with torch.no_grad():  # a non-uniform policy: varied maneuvers and instructions
        actor.module[0].module[-1].weight.normal_(0.0, 1.0)
    return actor.eval()


def assert_same_records(a: EpisodeRecords, b: EpisodeRecords) -> None:
    for field in dataclasses.fields(EpisodeRecords):
        x, y = getattr(a, field.name), getattr(b, field.name)
        assert (x is None) == (y is None), field.name
        if x is not None:
            assert torch.equal(x, y), field.name


def test_run_episodes_is_reproducible_for_a_seed(params, actor):
    first = run_episodes(GuidanceEnv(params, num_envs=16, seed=5), actor, trajectories=16)
    torch.manual_seed(999)  # the global RNG must not matter
    again = run_episodes(GuidanceEnv(params, num_envs=16, seed=5), actor, trajectories=16)
    assert_same_records(first, again)
    other = run_episodes(GuidanceEnv(params, num_envs=16, seed=6), actor, trajectories=16)
    assert not torch.equal(first.initial_aircraft_state, other.initial_aircraft_state)

    # Reseeding the same environment replays the same episodes.
    env = GuidanceEnv(params, num_envs=16, seed=0)
    env.set_seed(5)
    assert_same_records(first, run_episodes(env, actor, trajectories=16))


def test_run_episodes_records_are_consistent(params, actor):
    result = run_episodes(GuidanceEnv(params, num_envs=16, seed=5), actor, trajectories=16)
    assert result.outcome.shape == (16,)
    assert bool((result.outcome != Outcome.RUNNING).all())  # every episode ends within max_decisions
    assert bool(((result.decisions >= 1) & (result.decisions <= params.max_decisions)).all())
    assert bool(((result.instructions >= 0) & (result.instructions <= result.decisions)).all())
    assert int(result.instructions.sum()) > 0
    steps = int(result.decisions.max())
    assert result.trajectory_aircraft.shape == (16, steps + 1, 7)
    assert result.trajectory_destination.shape == (16, steps + 1, 4)
    assert torch.equal(result.trajectory_aircraft[:, 0], result.initial_aircraft_state)
    # A finished episode's trajectory stays frozen at its last state.
    for row in range(16):
        frozen = result.trajectory_aircraft[row, int(result.decisions[row]):]
        assert torch.equal(frozen, frozen[:1].expand_as(frozen))
    summary = summarise(result)
    assert sum(summary["outcomes"].values()) == 16


def test_run_episodes_keeps_the_paths_of_the_first_episodes_only(params, actor):
    every = run_episodes(GuidanceEnv(params, num_envs=16, seed=5), actor, trajectories=16)
    first = run_episodes(GuidanceEnv(params, num_envs=16, seed=5), actor, trajectories=3)
    assert torch.equal(first.trajectory_aircraft, every.trajectory_aircraft[:3])
    assert torch.equal(first.trajectory_destination, every.trajectory_destination[:3])
    for field in ("outcome", "decisions", "instructions", "episode_return", "final_distance"):
        assert torch.equal(getattr(first, field), getattr(every, field)), field  # the episodes are the same
    more = run_episodes(GuidanceEnv(params, num_envs=16, seed=5), actor, trajectories=100)
    assert torch.equal(more.trajectory_aircraft, every.trajectory_aircraft)
    none = run_episodes(GuidanceEnv(params, num_envs=16, seed=5), actor)
    assert none.trajectory_aircraft is None and none.trajectory_destination is None
    with pytest.raises(ValueError, match=r"^trajectories=-1 is not allowed: an integer >= 0"):
        run_episodes(GuidanceEnv(params, num_envs=16, seed=5), actor, trajectories=-1)


@torch.no_grad()  # as run_episodes: the compiled simulator's compilation is the same one
def _stepping_every_row(env: GuidanceEnv, actor) -> EpisodeRecords:
    """What run_episodes records, from TorchRL's ``env.step`` on the whole batch until every row is done."""
    td = env.reset()
    initial = td["aircraft_state"].clone()
    aircraft, destination = [td["aircraft_state"].clone()], [td["destination_state"].clone()]
    keys = ("aircraft_state", "destination_state", "outcome", "step_count", "instruction_count", "episode_return")
    final, running = td.select(*keys).clone(), torch.ones(env.batch_size, dtype=torch.bool)
    with set_exploration_type(ExplorationType.DETERMINISTIC):
        while bool(running.any()):
            td = env.step(actor(td))
            step = td["next"]
            aircraft.append(torch.where(running[:, None], step["aircraft_state"], aircraft[-1]))
            destination.append(torch.where(running[:, None], step["destination_state"], destination[-1]))
            finished = running & step["done"].squeeze(-1)
            final = step.select(*keys).where(finished, final)
            running &= ~finished
            td = step_mdp(td)
    relative = final["aircraft_state"][:, :2] - final["destination_state"][:, :2]
    return EpisodeRecords(initial, final["outcome"], final["step_count"], final["instruction_count"],
                          final["episode_return"], relative.norm(dim=-1), torch.stack(aircraft, 1),
                          torch.stack(destination, 1))


def test_run_episodes_flies_the_episodes_of_the_env_step(compose_train, tiny_args, actor):
    """Stepping only the rows still flying gives every record of TorchRL's step of the whole batch, bit for bit,
    with the irregular destination's redraws (the env's generator) too; and its paths, for the rows it keeps."""
    cfg = compose_train(*tiny_args({"simulation.max_decisions": 12}), "task=irregular")
    irregular = to_guidance_parameters(cfg.task, cfg.reward, cfg.simulation)
    expected = _stepping_every_row(GuidanceEnv(irregular, num_envs=40, seed=3), actor)
    result = run_episodes(GuidanceEnv(irregular, num_envs=40, seed=3), actor, trajectories=40)
    assert len(set(result.decisions.tolist())) > 2  # episodes of different lengths: rows leave at different steps
    assert_same_records(result, expected)


def test_run_episodes_flies_any_policy_module_as_it_flies_the_actor(params, actor):
    """An actor of make_actor flies as its CategoricalSampler; any other module (here the same actor inside a
    TensorDictSequential) is called as it is: the same episodes either way."""
    from tensordict.nn import TensorDictSequential

    wrapped = TensorDictSequential(actor)
    result = run_episodes(GuidanceEnv(params, num_envs=16, seed=5), wrapped, trajectories=4)
    assert_same_records(result, run_episodes(GuidanceEnv(params, num_envs=16, seed=5), actor, trajectories=4))
    assert len(set(result.instructions.tolist())) > 1


@pytest.mark.slow  # the training's compiled simulator: half a minute to compile on a cold cache
def test_run_episodes_flies_the_episodes_of_the_env_step_with_the_compiled_simulator():
    """With the compiled simulator a row's result depends on its place in the batch unless the batch is a whole
    number of vectors (run_episodes pads it, agrl.core.compiled.padded_rows): the shipped agent's 1008 episodes, whose
    rows leave one by one, against TorchRL's step of the whole batch of 1008 (a multiple of 16 rows)."""
    from agrl.rl.models import load_agent

    actor, saved, _ = load_agent("baseline")

    def episodes() -> GuidanceEnv:
        return GuidanceEnv.for_saved_agent(saved, 1008, seed=11, compile=True)

    result = run_episodes(episodes(), actor, trajectories=1008)
    assert len(set(result.decisions.tolist())) > 20
    assert_same_records(result, _stepping_every_row(episodes(), actor))


def test_counters_match_a_hand_count_of_the_replayed_actions(params, actor):
    """Record the actions of an evaluation, replay them through a fresh env, count decisions and maneuver
    changes by hand (the aircraft starts in steady flight, action 0) and compare with the records. The actor sees
    the rows still flying, in order; the replay steps every row and gives those rows the recorded actions."""
    assert MANEUVER_NAMES[0] == "steady_flight"
    actions = []

    def recording_actor(td):
        td = actor(td)
        actions.append(td["action"].clone())
        return td

    result = run_episodes(GuidanceEnv(params, num_envs=16, seed=5), recording_actor)
    env = GuidanceEnv(params, num_envs=16, seed=5)
    td = env.reset()
    decisions = [None] * 16
    outcomes, env_counts = [None] * 16, [None] * 16
    flown = torch.zeros(16, len(actions), dtype=torch.int64)
    for step, action in enumerate(actions):
        flying = torch.tensor([decision is None for decision in decisions])
        flown[flying, step] = action  # fails unless the evaluation flew exactly the rows still flying here
        td["action"] = flown[:, step]
        td = env.step(td)
        for row in range(16):
            if decisions[row] is None and bool(td["next", "done"][row]):
                decisions[row] = step + 1
                outcomes[row] = int(td["next", "outcome"][row])
                env_counts[row] = (int(td["next", "step_count"][row]), int(td["next", "instruction_count"][row]))
        td = step_mdp(td)
    assert all(decision is not None for decision in decisions)
    instructions = []
    for row in range(16):
        previous, changes = 0, 0
        for action in flown[row, : decisions[row]].tolist():
            changes += action != previous
            previous = action
        instructions.append(changes)
    assert result.decisions.tolist() == decisions
    assert result.instructions.tolist() == instructions
    assert result.outcome.tolist() == outcomes
    assert env_counts == list(zip(decisions, instructions, strict=True))
    # The hand count is not trivial: some episodes change maneuver, some decisions keep it.
    assert 0 < sum(instructions) < sum(decisions)


class SteppingClock:
    """A stand-in for the ``time`` module whose ``perf_counter`` advances by given durations per query."""

    def __init__(self, durations: list[float]):
        self.now, self.calls, self.durations = 0.0, 0, durations

    def perf_counter(self) -> float:
        # Calls alternate: start of query i, end of query i (which is i's duration later).
        if self.calls % 2:
            self.now += self.durations[self.calls // 2]
        else:
            self.now += 1.0  # time between queries must not count
        self.calls += 1
        return self.now


def test_instruction_latency_is_the_median_of_the_timed_single_aircraft_queries(params, actor, monkeypatch):
    import agrl.rl.evaluation as evaluation

    queries, warm_up = 21, 10
    # Distinct durations (s), shuffled; the warm-up queries are slow and must be left out.
    durations = [5.0] * warm_up + [(8 * i % queries + 1) * 1e-4 for i in range(queries)]
    clock = SteppingClock(durations)
    batch_sizes = []

    def counting_actor(td):
        batch_sizes.append(tuple(td.batch_size))
        return actor(td)

    monkeypatch.setattr(evaluation, "time", clock)
    latency = instruction_latency_ms(GuidanceEnv(params, num_envs=4, seed=0), counting_actor, queries=queries)
    expected = 1000.0 * sorted(durations[warm_up:])[queries // 2]  # the median of 21 values: the 11th
    assert latency == pytest.approx(expected, rel=1e-9)
    assert expected == pytest.approx(1.1, rel=1e-9)  # 11 x 0.1 ms
    assert clock.calls == 2 * (queries + warm_up)
    assert batch_sizes == [(1,)] * (queries + warm_up)  # one aircraft per query


def test_instruction_latency_of_a_real_query_is_a_finite_positive_time(params, actor):
    latency = instruction_latency_ms(GuidanceEnv(params, num_envs=4, seed=0), actor, queries=20)
    assert math.isfinite(latency) and latency > 0.0


def _summary(success_rate: float, instructions: float, seconds: float) -> dict:
    return {"success_rate": success_rate, "instructions_per_episode": instructions, "training_wall_time_s": seconds}


def test_a_run_that_meets_the_search_target_costs_its_training_seconds():
    assert search_objective(_summary(0.996, 6.9, 75.5), 0.995, 7.0, 60.0) == 75.5
    assert search_objective(_summary(0.995, 7.0, 75.5), 0.995, 7.0, 60.0) == 75.5  # the target itself meets it


def test_a_run_that_misses_pays_per_point_of_success_and_per_instruction():
    # 0.5 points of success short and 1.5 instructions over: 2 x 60 s more than its 40 s.
    assert search_objective(_summary(0.990, 8.5, 40.0), 0.995, 7.0, 60.0) == pytest.approx(40.0 + 60.0 * 2.0)
    # A shorter run that misses scores worse than a longer one that meets the target a minute later.
    assert search_objective(_summary(0.985, 6.0, 30.0), 0.995, 7.0, 60.0) > search_objective(
        _summary(0.996, 6.0, 89.0), 0.995, 7.0, 60.0)
