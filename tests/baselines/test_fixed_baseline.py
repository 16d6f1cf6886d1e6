"""The shipped baseline (agrl/baselines/fixed_baseline.pt) still flies as well as its own evaluation record says.

The documented numbers are read from the file (``torch.load(..., weights_only=True)["evaluation"]``, the
``eval.json`` that ``python -m agrl.export --evaluation`` embedded), never written here: a new baseline with a
record of the same shape is checked against its own record.

The evaluation is rerun with the eager simulator on the record's own episodes (``evaluation_seed``, ``episodes``;
slow: 1 000 episodes of 20 ms steps take the better part of a minute on one core), where a healthy library
reproduces the record almost exactly, and in the fast suite on 250 other episodes of the same task. The margin is
3 standard errors of an estimate over the rerun's episode count (for success: ``3 sqrt(p (1 - p) / n)`` with the
record's ``p``, at least one episode; for instructions: 3 x the episodes' standard deviation / sqrt(n)): a real
regression in the simulator, the observation or the actor moves the result by more than that, numerical noise
(compiled vs eager float differences flipping a borderline episode) and another draw of episodes do not.
"""

from __future__ import annotations

import math

import pytest
import torch

from agrl.baselines import BASELINE_FILE
from agrl.envs.guidance import GuidanceEnv
from agrl.rl.evaluation import run_episodes, summarise
from agrl.rl.models import load_agent

pytestmark = pytest.mark.usefixtures("torch_one_thread")

STANDARD_ERRORS = 3


@pytest.fixture(scope="module")
def record() -> dict:
    return torch.load(BASELINE_FILE, weights_only=True)["evaluation"]


#: Episodes of the fast suite's rerun, drawn with a seed the record did not use.
FRESH_EPISODES = 250


@pytest.fixture(scope="module", params=["fresh", pytest.param("record", marks=pytest.mark.slow)])
def rerun(request, record):
    """(summary, records) of the baseline, eager simulator: on the record's own episodes, or on fresh ones."""
    actor, saved, _ = load_agent("baseline")
    if request.param == "record":
        episodes, seed = record["episodes"], record["evaluation_seed"]
    else:
        episodes, seed = FRESH_EPISODES, record["evaluation_seed"] + 1
    env = GuidanceEnv.for_saved_agent(saved, episodes, seed=seed, compile=False)
    records = run_episodes(env, actor)
    return summarise(records), records


def test_the_record_is_a_1000_episode_evaluation_of_the_fixed_task(record):
    assert record["episodes"] == 1000
    assert record["task"] == "fixed"
    assert sum(record["outcomes"].values()) == record["episodes"]
    assert record["success_rate"] == record["outcomes"]["success"] / record["episodes"]


def test_success_rate_is_at_least_the_documented_one_minus_3_standard_errors(record, rerun):
    summary, records = rerun
    documented, episodes = record["success_rate"], records.instructions.numel()
    margin = max(STANDARD_ERRORS * math.sqrt(documented * (1 - documented) / episodes), 1 / episodes)
    assert summary["episodes"] == episodes
    assert summary["success_rate"] >= documented - margin, (summary["outcomes"], record["outcomes"], margin)


def test_instructions_per_episode_match_the_documented_mean_within_3_standard_errors(record, rerun):
    summary, records = rerun
    instructions = records.instructions.double()
    margin = STANDARD_ERRORS * float(instructions.std()) / math.sqrt(instructions.numel())
    assert summary["instructions_per_episode"] == pytest.approx(float(instructions.mean()))
    assert abs(summary["instructions_per_episode"] - record["instructions_per_episode"]) <= margin, margin
