"""Distillation of one agent's policy, or of an ensemble's, into one network (DAgger); the CLI is :mod:`agrl.distill`.

Two uses: re-expressing an agent on another observation (the paper's equation 4), and compressing an ensemble
of agents (the mean of their action probabilities) into one network of the usual size.

Each round flies episodes of the teacher's task with the current student (the teacher in round 0), a share
``epsilon`` of the decisions random so that states off the path are seen too; the teacher labels every visited
state (its action probabilities and its value), and the student is trained on all rounds' states
(cross-entropy to the teacher's probabilities, squared error to its values).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Sequence
from pathlib import Path

import torch
from tensordict import TensorDict

from agrl.config import LEGACY_ACTIONS, ConfigError, saved_agent_config, saved_guidance_parameters
from agrl.core.observation import observation_function
from agrl.envs.guidance import NUM_ACTIONS, GuidanceEnv
from agrl.rl.checkpoint import load_checkpoint, load_module_state, resolve_checkpoint_path, save_checkpoint
from agrl.rl.evaluation import run_episodes, summarise
from agrl.rl.models import logits_network, make_actor, make_critic, make_ensemble_actor


def _collect(env: GuidanceEnv, act, epsilon: float, generator: torch.Generator) -> TensorDict:
    """The states ``act`` (observation kind of the env -> action) visits in one decision budget, with auto-reset."""
    states = []
    td = env.reset()
    for _ in range(env.params.max_decisions):
        states.append(td.select("aircraft_state", "destination_state", "last_action").clone())
        action = act(td)
        random = torch.rand(action.shape, generator=generator, device=action.device) < epsilon
        action = torch.where(random, torch.randint(0, NUM_ACTIONS, action.shape, generator=generator,
                                                   device=action.device), action)
        td = env.step_and_maybe_reset(td.set("action", action))[1]
    return torch.cat(states)


def _load_teachers(teachers: Sequence[str | Path]):
    """(paths, the first's saved config, observation, actor, value function): one teacher, or the ensemble of
    several (the mean of their action probabilities and of their values). An ensemble's members must share a
    task, a simulation and an observation; their rewards may differ (e.g. switch costs), the first's is kept."""
    if not teachers:
        raise ConfigError("no teacher given: name one checkpoint, or several for an ensemble")
    paths = [resolve_checkpoint_path(teacher) for teacher in teachers]
    payloads = [load_checkpoint(path, required=("actor", "critic", "config")) for path in paths]
    saved = payloads[0]["config"]
    observation = saved_agent_config(saved).observation
    actors, critics = [], []
    for path, payload in zip(paths, payloads, strict=True):
        agent = saved_agent_config(payload["config"])
        actions = payload["config"].get("actions", LEGACY_ACTIONS)["name"]
        if actions != LEGACY_ACTIONS["name"]:
            raise ConfigError(f"{path}: actions={actions} is not allowed as a teacher: distillation takes agents of "
                              "the paper's maneuvers")
        for section in ("task", "simulation"):
            if payload["config"].get(section) != saved.get(section):
                raise ConfigError(f"{path}: its {section} differs from {paths[0]}'s; an ensemble's teachers must "
                                  "share task and simulation")
        if agent.observation != observation:
            raise ConfigError(f"{path}: observation={agent.observation} is not allowed in this ensemble: "
                              f"{paths[0]} reads {observation}")
        actor = make_actor(agent.actor_hidden, agent.activation, observation=agent.observation)
        critic = make_critic(agent.critic_hidden, agent.activation, observation=agent.observation)
        load_module_state(actor, payload["actor"], path, "actor")
        load_module_state(critic, payload["critic"], path, "critic")
        actors.append(actor.eval())
        critics.append(critic.module.eval())
    actor = actors[0] if len(actors) == 1 else make_ensemble_actor(actors).eval()

    def value(observations: torch.Tensor) -> torch.Tensor:
        return torch.stack([critic(observations) for critic in critics]).mean(0)

    return paths, saved, observation, actor, value


def distill(
    teachers: str | Path | Sequence[str | Path], destination: str | Path, *, observation: str = "absolute",
    rounds: int = 4, envs: int = 2048, epochs: int = 8, minibatch: int = 4096, learning_rate: float = 1e-3,
    epsilon: float = 0.1, evaluation_episodes: int = 1000, seed: int = 0, compile: bool = True,
    init: str | Path | None = None, log=print,
) -> dict:
    """Write the student checkpoint to ``destination``; return its summary (agreement, and the student's and
    the teacher's evaluations on the same ``evaluation_episodes`` episodes of the teacher's task, seed
    ``seed + 1_000_003``). Several ``teachers`` make one ensemble teacher (:func:`make_ensemble_actor`: the mean
    of their action probabilities, and of their values). ``compile`` fuses the simulator (as training does).
    ``init`` (a checkpoint of the student's network and observation) is where the student starts instead of a
    fresh network: for an ensemble of fine-tunes of one agent, their weight average is already close to it."""
    if rounds < 1 or envs < 1 or epochs < 1:
        raise ConfigError(f"rounds={rounds}, envs={envs}, epochs={epochs} are not allowed: each >= 1")
    if isinstance(teachers, (str, Path)):
        teachers = [teachers]
    paths, saved, teacher_observation, teacher_actor, teacher_value = _load_teachers(teachers)
    agent = saved_agent_config(saved)
    torch.manual_seed(seed)
    student_actor = make_actor(agent.actor_hidden, agent.activation, observation=observation)
    student_critic = make_critic(agent.critic_hidden, agent.activation, observation=observation)
    if init is not None:
        init_path = resolve_checkpoint_path(init)
        start = load_checkpoint(init_path, required=("actor", "critic", "config"))
        if saved_agent_config(start["config"]).observation != observation:
            raise ConfigError(f"{init_path}: observation={saved_agent_config(start['config']).observation} is not "
                              f"allowed as the start of a student reading {observation}")
        load_module_state(student_actor, start["actor"], init_path, "actor")
        load_module_state(student_critic, start["critic"], init_path, "critic")
    params = saved_guidance_parameters(saved, compile=compile)
    simulation = params.simulation
    teacher_input, student_input = observation_function(teacher_observation), observation_function(observation)

    def inputs(function, states: TensorDict) -> torch.Tensor:
        return function(states["aircraft_state"], states["destination_state"], states["last_action"],
                        simulation.airspace, simulation.limits)

    def act(network, function):
        return lambda td: network(inputs(function, td)).argmax(-1)

    teacher_logits, student_logits = logits_network(teacher_actor), logits_network(student_actor)
    env = GuidanceEnv(params, num_envs=envs, seed=seed)
    generator = torch.Generator().manual_seed(seed + 1)
    optimiser = torch.optim.Adam([*student_actor.parameters(), *student_critic.parameters()], lr=learning_rate)
    # All rounds' labelled states; the teacher is frozen, so each state is labelled once, in the round it was flown.
    student_obs, target_probability, target_value = [], [], []
    for round_index in range(rounds):
        started = time.perf_counter()
        with torch.no_grad():
            flyer = (act(teacher_logits, teacher_input) if round_index == 0 else act(student_logits, student_input))
            states = _collect(env, flyer, epsilon, generator)
            teacher_obs = inputs(teacher_input, states)
            target_probability.append(teacher_logits(teacher_obs).softmax(-1))
            target_value.append(teacher_value(teacher_obs))
            student_obs.append(inputs(student_input, states))
        observations, probabilities, values = (torch.cat(part) for part in (student_obs, target_probability,
                                                                             target_value))
        for _ in range(epochs):
            for index in torch.randperm(len(observations), generator=generator).split(minibatch):
                log_probability = student_logits(observations[index]).log_softmax(-1)
                policy_loss = -(probabilities[index] * log_probability).sum(-1).mean()
                value_loss = (student_critic.module(observations[index]) - values[index]).pow(2).mean()
                optimiser.zero_grad()
                # Values are returns of order 10-20 and their squared errors of order 1-100, the cross-entropy of
                # order 1: the 0.01 keeps the critic's fit from driving the shared step size.
                (policy_loss + 0.01 * value_loss).backward()
                optimiser.step()
        with torch.no_grad():
            agreement = float((student_logits(observations).argmax(-1) == probabilities.argmax(-1)).float().mean())
        log(f"round {round_index + 1}/{rounds}: {len(observations)} states, agreement with the teacher "
            f"{agreement:.4f}, {time.perf_counter() - started:.0f} s")

    def evaluation(actor, observation_kind: str) -> dict:
        episodes = GuidanceEnv(dataclasses.replace(params, compile=False), num_envs=evaluation_episodes,
                               seed=seed + 1_000_003, observation=observation_kind)
        with torch.no_grad():
            return summarise(run_episodes(episodes, actor))

    summary = {"distilled_from": [str(path) for path in paths], "initialised_from": None if init is None else str(init),
               "observation": observation, "rounds": rounds, "states": len(observations), "agreement": agreement,
               "evaluation": evaluation(student_actor.eval(), observation),
               "teacher_evaluation": evaluation(teacher_actor, teacher_observation)}
    config = {**saved, "agent": {**saved["agent"], "observation": observation}}
    save_checkpoint({"actor": student_actor.state_dict(), "critic": student_critic.state_dict(), "config": config,
                     "exported_from": str(paths[0]), "distillation": summary}, destination)
    return summary
