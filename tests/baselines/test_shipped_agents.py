"""The shipped agents (agrl.baselines.SHIPPED_AGENTS): every name is accepted wherever a checkpoint is, loads safely,
and carries an evaluation record that the agent still flies (the rerun is slow-marked: 10 000 episodes each)."""

from __future__ import annotations

import math
import subprocess
import sys

import pytest
import torch

from agrl.baselines import BASELINE_FILE, SHIPPED_AGENTS
from agrl.cli import check_overrides
from agrl.config import ConfigError, saved_agent_config
from agrl.envs.guidance import GuidanceEnv
from agrl.guide import Guide, GuideError
from agrl.rl.checkpoint import CheckpointError, load_checkpoint, resolve_checkpoint_path
from agrl.rl.evaluation import run_episodes, summarise
from agrl.rl.models import load_agent

NAMES = list(SHIPPED_AGENTS)
ALLOWED = ("baseline, baseline-first-search, baseline-two-stage, baseline-stage1, "
           "baseline-both-terms, baseline-targets, baseline-absolute")
#: The input each agent's network reads.
OBSERVATIONS = {"baseline": "relative", "baseline-first-search": "relative", "baseline-two-stage": "relative",
                "baseline-stage1": "relative", "baseline-both-terms": "relative",
                "baseline-targets": "relative", "baseline-absolute": "absolute"}
#: The actions each agent gives (conf/actions).
ACTIONS = {name: "targets" if name == "baseline-targets" else "maneuvers" for name in OBSERVATIONS}


def test_the_names_are_the_documented_ones():
    assert ", ".join(NAMES) == ALLOWED
    assert SHIPPED_AGENTS["baseline"].file == BASELINE_FILE
    assert len({agent.file for agent in SHIPPED_AGENTS.values()}) == len(NAMES)


@pytest.mark.parametrize("name", NAMES)
def test_each_name_resolves_to_its_file_and_loads_without_pickle(name):
    path = resolve_checkpoint_path(name)
    assert path == SHIPPED_AGENTS[name].file and path.parent.name == "baselines"
    # Only tensors and plain data: a weights-only load with no allow-list at all reads it.
    assert isinstance(torch.load(path, map_location="cpu", weights_only=True), dict)
    assert torch.serialization.get_unsafe_globals_in_checkpoint(path) == []
    load_checkpoint(path, required=("actor", "critic", "config"))
    actor, saved, loaded_from = load_agent(name)
    assert loaded_from == path
    assert saved_agent_config(saved).observation == OBSERVATIONS[name]


@pytest.mark.parametrize("name", NAMES)
def test_each_evaluation_record_is_a_consistent_summary(name):
    evaluations = SHIPPED_AGENTS[name].evaluations()
    assert evaluations, f"{name} has no evaluation"
    for evaluation in evaluations:
        outcomes = evaluation["outcomes"]
        assert sum(outcomes.values()) == evaluation["episodes"] >= 1000
        assert evaluation["success_rate"] == pytest.approx(outcomes["success"] / evaluation["episodes"], abs=1e-6)
        low, high = evaluation["success_rate_ci95"]
        assert low <= evaluation["success_rate"] <= high
        assert f"checkpoint={name} " in evaluation["command"] and f"seed={evaluation['seed']}" in evaluation["command"]
        assert "episodes.csv" not in str(evaluation) and "trajectories" not in evaluation  # summaries only
    seeds = [evaluation["seed"] for evaluation in evaluations]
    assert len(seeds) == len(set(seeds)), f"{name}: an evaluation seed is recorded twice"


@pytest.mark.parametrize("name", NAMES)
def test_each_name_is_accepted_before_hydra_runs(name):
    observation = OBSERVATIONS[name]
    check_overrides(["method=pretrained", f"method.baseline={name}", f"agent.observation={observation}",
                     f"actions={ACTIONS[name]}"], "config")
    check_overrides([f"checkpoint={name}"], "evaluate")


@pytest.mark.parametrize(("baseline", "actions"), [("baseline-targets", "maneuvers"), ("baseline", "targets")])
def test_starting_from_an_agent_of_the_other_action_set_is_one_line(baseline, actions):
    """What python -m agrl.train checks before Hydra runs (agrl.train.check_inputs)."""
    from agrl.config import compose_checked, load_config
    from agrl.train import check_inputs

    trained = ACTIONS[baseline]
    config = load_config(compose_checked("method=pretrained", f"method.baseline={baseline}", f"actions={actions}"))
    with pytest.raises(CheckpointError) as error:
        check_inputs(config)
    assert str(error.value) == (f"{SHIPPED_AGENTS[baseline].file}: actions={actions} is not allowed with this "
                                f"baseline: it was trained with actions={trained}; train Z with the same")


def test_an_unknown_name_is_one_line_listing_the_names():
    with pytest.raises(CheckpointError) as error:
        resolve_checkpoint_path("baseline-stage2")
    assert str(error.value) == ("baseline-stage2: no such checkpoint file or run directory; allowed: a checkpoint "
                                f"file, a run directory, or a shipped agent ({ALLOWED})")
    with pytest.raises(ConfigError, match=rf"^method\.baseline: baseline-stage2: .*shipped agent \({ALLOWED}\)$"):
        check_overrides(["method=reuse", "method.baseline=baseline-stage2"], "config")


def test_a_missing_shipped_file_is_one_line_with_its_recipe(monkeypatch):
    from agrl.baselines import ShippedAgent

    missing = ShippedAgent("baseline-gone", "no_such_agent.pt", "an agent whose file is absent", ("make train",))
    monkeypatch.setitem(SHIPPED_AGENTS, "baseline-gone", missing)
    with pytest.raises(CheckpointError) as error:
        resolve_checkpoint_path("baseline-gone")
    assert str(error.value) == (f"{missing.file}: the shipped agent baseline-gone is missing from this installation; "
                                "reinstall agrl, or make one (make train) and pass its checkpoint path instead of "
                                "'baseline-gone'")


def test_a_file_named_like_a_shipped_agent_does_not_shadow_it(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "baseline-stage1").write_bytes(b"not a checkpoint")
    assert resolve_checkpoint_path("baseline-stage1") == SHIPPED_AGENTS["baseline-stage1"].file


def test_guide_loads_the_relative_agents_and_refuses_the_absolute_one():
    stage1 = Guide.load("baseline-stage1")
    assert stage1.source == str(SHIPPED_AGENTS["baseline-stage1"].file)
    assert Guide.load("baseline-both-terms").instruct((-5000.0, 0.0, 1000.0, 200.0, 0.0, 0.0, 0.0),
                                                      (0.0, 0.0, 0.0, 0.0), 0) in range(7)
    with pytest.raises(GuideError, match=r"fixed_baseline_absolute\.pt: agent\.observation=absolute is not allowed"):
        Guide.load("baseline-absolute")


def test_the_listing_names_every_agent_with_its_file_and_evaluations():
    result = subprocess.run([sys.executable, "-m", "agrl.baselines"], capture_output=True, text=True, timeout=60,
                            check=True)
    for agent in SHIPPED_AGENTS.values():
        assert f"{agent.name}: agrl/baselines/{agent.filename}\n" in result.stdout
    assert "99.83 % at 6.86 instructions (fixed, 10000 episodes, seed 777)" in result.stdout


@pytest.mark.slow  # 10 000 episodes per agent on the eager simulator, one thread: 11-31 s each
@pytest.mark.usefixtures("torch_one_thread")
@pytest.mark.parametrize("name", NAMES)
def test_each_agent_still_flies_its_first_recorded_evaluation(name):
    """The first recorded evaluation (of the agent's own task), rerun on its own episodes with the eager simulator,
    within 3 standard errors (the margin tests/baselines/test_fixed_baseline.py explains)."""
    record = SHIPPED_AGENTS[name].evaluations()[0]
    actor, saved, _ = load_agent(name)
    assert record["task"] == saved["task"]["name"]
    env = GuidanceEnv.for_saved_agent(saved, record["episodes"], seed=record["seed"], compile=False)
    records = run_episodes(env, actor)
    summary = summarise(records)
    rate, episodes = record["success_rate"], record["episodes"]
    assert summary["success_rate"] >= rate - max(3 * math.sqrt(rate * (1 - rate) / episodes), 1 / episodes)
    instructions = records.instructions.double()
    margin = 3 * float(instructions.std()) / math.sqrt(instructions.numel())
    assert abs(summary["instructions_per_episode"] - record["instructions_per_episode"]) <= margin


@pytest.mark.parametrize("override", ["actions.headings=8", "actions.altitude_step=1000", "actions.cruise_speed=180"])
def test_reusing_a_target_agent_with_another_target_table_is_one_line(override):
    """B's action indices mean what they mean in Z's env only with the same target table."""
    from agrl.config import compose_checked, load_config
    from agrl.train import check_inputs

    config = load_config(compose_checked("actions=targets", "task=uniform", "method=reuse",
                                         "method.baseline=baseline-targets", override))
    with pytest.raises(CheckpointError) as error:
        check_inputs(config)
    assert str(error.value).startswith(f"{SHIPPED_AGENTS['baseline-targets'].file}: this run's target table is not "
                                       "allowed with this baseline")
