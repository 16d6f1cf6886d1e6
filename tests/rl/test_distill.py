"""Distillation: the shipped baseline's policy re-expressed on equation 4's inputs (agrl.rl.distill)."""

from __future__ import annotations

import pytest
import torch

from agrl.config import saved_agent_config
from agrl.core.observation import absolute_observation, observation_size, policy_observation
from agrl.envs.guidance import GuidanceEnv
from agrl.evaluate import load_agent
from agrl.rl.checkpoint import load_checkpoint
from agrl.rl.distill import distill

pytestmark = pytest.mark.usefixtures("torch_one_thread")


@pytest.fixture(scope="module")
def student(tmp_path_factory):
    path = tmp_path_factory.mktemp("distill") / "student.pt"
    summary = distill("baseline", path, rounds=2, envs=48, epochs=40, minibatch=512, evaluation_episodes=64,
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
    assert summary["rounds"] == 2 and summary["states"] == 2 * 48 * 200  # two rounds of a 200-decision budget


def test_the_student_flies_as_the_teacher_on_states_it_was_not_trained_on(student):
    path, _ = student
    student_actor, saved, _ = load_agent(str(path))
    teacher_actor, _, _ = load_agent("baseline")
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
    from agrl.config import saved_guidance_parameters
    from agrl.rl.evaluation import run_episodes, summarise

    path, summary = student
    actor, saved, _ = load_agent(str(path))
    env = GuidanceEnv(saved_guidance_parameters(saved, compile=False), num_envs=64, seed=1_000_003,
                      observation=saved_agent_config(saved).observation)
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
