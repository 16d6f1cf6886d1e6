"""Distillation: the shipped baseline's policy re-expressed on equation 4's inputs (agrl.rl.distill)."""

from __future__ import annotations

from pathlib import Path

import pytest
import torch

from agrl.config import saved_agent_config
from agrl.core.observation import absolute_observation, observation_size, policy_observation
from agrl.envs.guidance import GuidanceEnv
from agrl.rl.checkpoint import load_checkpoint
from agrl.rl.distill import distill
from agrl.rl.models import load_agent

pytestmark = pytest.mark.usefixtures("torch_one_thread")

#: The teachers' simulation: 10 substeps per 3 s decision instead of the baseline's 150 (a 0.3 s integration step
#: instead of 0.02 s), and a budget of 60 decisions instead of 200 (a collection round flies one budget).
COARSE_SIMULATION = {"integration_step": 0.3, "max_decisions": 60}


@pytest.fixture(scope="module")
def coarse_baseline(tmp_path_factory) -> Path:
    """The shipped baseline's networks and config, with :data:`COARSE_SIMULATION` in its saved simulation: a
    distillation flies its teacher's task as saved, and a round then costs about a fiftieth. What is distilled (the
    networks' answers on the visited states) does not depend on the step or the budget."""
    from agrl.rl.checkpoint import resolve_checkpoint_path, save_checkpoint

    payload = load_checkpoint(resolve_checkpoint_path("baseline"), required=("actor", "critic", "config"))
    config = {**payload["config"], "simulation": {**payload["config"]["simulation"], **COARSE_SIMULATION}}
    kept = {key: value for key, value in payload.items() if key != "config_yaml"}  # the YAML is of the old config
    return save_checkpoint({**kept, "config": config}, tmp_path_factory.mktemp("teacher") / "coarse_baseline.pt")


@pytest.fixture(scope="module")
def student(tmp_path_factory, coarse_baseline):
    path = tmp_path_factory.mktemp("distill") / "student.pt"
    summary = distill(coarse_baseline, path, rounds=2, envs=48, epochs=40, minibatch=512, evaluation_episodes=64,
                      compile=False, log=lambda line: None)
    return path, summary


def test_the_student_reads_the_absolute_observation_and_keeps_the_teachers_task(student):
    path, summary = student
    payload = load_checkpoint(path, required=("actor", "critic", "config", "distillation"))
    teacher = load_checkpoint(payload["exported_from"])
    assert saved_agent_config(payload["config"]).observation == "absolute"
    assert payload["config"]["task"] == teacher["config"]["task"]
    assert payload["actor"]["module.0.module.0.weight"].shape[1] == observation_size("absolute")
    assert payload["critic"]["module.0.weight"].shape[1] == observation_size("absolute")
    assert payload["config"]["simulation"] == teacher["config"]["simulation"]
    # Two rounds of the teacher's 60-decision budget.
    assert summary["rounds"] == 2 and summary["states"] == 2 * 48 * COARSE_SIMULATION["max_decisions"]


def test_the_student_flies_as_the_teacher_on_states_it_was_not_trained_on(student, coarse_baseline):
    path, _ = student
    student_actor, saved, _ = load_agent(str(path))
    teacher_actor, _, _ = load_agent(str(coarse_baseline))
    from agrl.config import saved_guidance_parameters

    params = saved_guidance_parameters(saved, compile=False)
    env = GuidanceEnv(params, num_envs=64, seed=123)
    states = env.rollout(40, policy=teacher_actor, break_when_any_done=False).reshape(-1)
    simulation = params.simulation
    fields = (states["aircraft_state"], states["destination_state"], states["last_action"], simulation.airspace,
              simulation.limits)
    teacher = teacher_actor.module[0](states.select().set("observation", policy_observation(*fields)))["logits"]
    learnt = student_actor.module[0](states.select().set("observation", absolute_observation(*fields)))["logits"]
    agreement = float((teacher.argmax(-1) == learnt.argmax(-1)).float().mean())
    chance = float((teacher.argmax(-1) == torch.randint(0, 7, teacher.shape[:1])).float().mean())
    assert agreement > 0.7 > chance + 0.4, (agreement, chance)


def test_the_written_student_gives_the_evaluation_in_its_summary(student):
    """The checkpoint, loaded as python -m agrl.evaluate loads it, flies the summary's evaluation episodes
    (seed + 1_000_003) to the same outcomes: the saved weights and observation are the ones evaluated."""
    from agrl.rl.evaluation import run_episodes, summarise

    path, summary = student
    actor, saved, _ = load_agent(str(path))
    env = GuidanceEnv.for_saved_agent(saved, 64, seed=1_000_003, compile=False)
    again = summarise(run_episodes(env, actor))
    assert summary["evaluation"]["episodes"] == again["episodes"] == 64
    assert summary["evaluation"]["outcomes"] == again["outcomes"]
    assert summary["evaluation"]["instructions_per_episode"] == pytest.approx(again["instructions_per_episode"])


def test_a_guide_refuses_the_absolute_student_in_one_line(student):
    from agrl.guide import Guide, GuideError

    path, _ = student
    with pytest.raises(GuideError, match=r"agent.observation=absolute is not allowed for a guide") as error:
        Guide.load(path)
    assert "\n" not in str(error.value)


@pytest.fixture(scope="module")
def ensemble_student(tmp_path_factory, coarse_baseline):
    """Two teachers that disagree on many states: the (coarse) baseline and a copy with perturbed weights."""
    from agrl.rl.checkpoint import save_checkpoint

    folder = tmp_path_factory.mktemp("ensemble")
    baseline = load_checkpoint(coarse_baseline, required=("actor", "critic", "config"))
    generator = torch.Generator().manual_seed(3)
    perturbed = {name: tensor + 0.3 * tensor.std() * torch.randn(tensor.shape, generator=generator)
                 for name, tensor in baseline["actor"].items()}
    other = save_checkpoint({**baseline, "actor": perturbed}, folder / "perturbed.pt")
    path = folder / "student.pt"
    summary = distill([coarse_baseline, other], path, observation="relative", rounds=2, envs=48, epochs=40,
                      minibatch=512, evaluation_episodes=64, compile=False, log=lambda line: None)
    return path, other, summary


def test_an_ensemble_of_teachers_is_distilled_into_one_network_of_the_usual_size(ensemble_student, coarse_baseline):
    from agrl.config import saved_guidance_parameters
    from agrl.rl.models import logits_network, make_ensemble_actor

    path, other, summary = ensemble_student
    payload = load_checkpoint(path, required=("actor", "critic", "config", "distillation"))
    baseline = load_checkpoint(payload["exported_from"], required=("actor",))
    assert {name: list(t.shape) for name, t in payload["actor"].items()} == {
        name: list(t.shape) for name, t in baseline["actor"].items()}
    assert len(summary["distilled_from"]) == 2 and summary["distilled_from"][1] == str(other)
    assert summary["teacher_evaluation"]["episodes"] == summary["evaluation"]["episodes"] == 64

    members = [load_agent(reference)[0] for reference in (str(coarse_baseline), str(other))]
    ensemble = make_ensemble_actor(members)
    student_actor, saved, _ = load_agent(str(path))
    params = saved_guidance_parameters(saved, compile=False)
    states = GuidanceEnv(params, num_envs=64, seed=321).rollout(40, policy=ensemble, break_when_any_done=False)
    observations = states.reshape(-1)["observation"]
    teacher = logits_network(ensemble)(observations).argmax(-1)
    members_actions = [logits_network(member)(observations).argmax(-1) for member in members]
    learnt = logits_network(student_actor)(observations).argmax(-1)
    agreement = float((learnt == teacher).float().mean())
    assert bool((members_actions[0] != members_actions[1]).any())  # the ensemble is neither member alone
    assert agreement > 0.7, agreement


def test_teachers_of_different_observations_are_refused_in_one_line(student, coarse_baseline, tmp_path):
    from agrl.config import ConfigError

    absolute_student, _ = student  # of the coarse teacher's task and simulation: only the observation differs
    with pytest.raises(ConfigError, match="observation=absolute is not allowed in this ensemble") as error:
        distill([coarse_baseline, absolute_student], tmp_path / "out.pt", observation="relative", compile=False,
                log=lambda line: None)
    assert "\n" not in str(error.value) and not (tmp_path / "out.pt").exists()


def test_a_student_started_from_its_teacher_starts_where_it_stands(tmp_path, coarse_baseline):
    """``init`` is where the student starts: from the teacher itself one short epoch leaves it nearly the teacher
    (Adam's first steps move it by about the learning rate whatever the gradient), where a fresh student after
    the same epoch agrees far less."""
    settings = dict(observation="relative", rounds=1, envs=32, epochs=1, minibatch=512, evaluation_episodes=32,
                    compile=False, log=lambda line: None)
    started = distill(coarse_baseline, tmp_path / "started.pt", init="baseline", **settings)  # its networks
    fresh = distill(coarse_baseline, tmp_path / "fresh.pt", **settings)
    assert started["initialised_from"] == "baseline" and fresh["initialised_from"] is None
    assert started["agreement"] > 0.95 and started["agreement"] > fresh["agreement"] + 0.2, (started, fresh)


def test_a_start_of_another_observation_is_refused_in_one_line(student, tmp_path):
    from agrl.config import ConfigError

    absolute_student, _ = student
    with pytest.raises(ConfigError, match="is not allowed as the start of a student reading relative") as error:
        distill("baseline", tmp_path / "out.pt", observation="relative", compile=False, init=absolute_student,
                log=lambda line: None)
    assert "\n" not in str(error.value)


def test_an_agent_holding_targets_is_refused_as_a_teacher(tmp_path):
    from agrl.baselines import SHIPPED_AGENTS
    from agrl.config import ConfigError

    with pytest.raises(ConfigError) as error:
        distill("baseline-targets", tmp_path / "student.pt")
    assert str(error.value) == (f"{SHIPPED_AGENTS['baseline-targets'].file}: actions=targets is not allowed as a "
                                "teacher: distillation takes agents of the paper's maneuvers")
    assert not (tmp_path / "student.pt").exists()
