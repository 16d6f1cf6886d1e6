"""Distillation of one agent's policy onto another observation (DAgger); the CLI is :mod:`agrl.distill`.

Each round flies episodes of the teacher's task with the current student (the teacher in round 0), a share
``epsilon`` of the decisions random so that states off the path are seen too; the teacher labels every visited
state (its action probabilities and its value), and the student is trained on all rounds' states
(cross-entropy to the teacher's probabilities, squared error to its values).
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path

import torch
from tensordict import TensorDict

from agrl.config import ConfigError, saved_agent_config, saved_guidance_parameters
from agrl.core.observation import observation_function
from agrl.envs.guidance import NUM_ACTIONS, GuidanceEnv
from agrl.rl.checkpoint import load_checkpoint, load_module_state, resolve_checkpoint_path, save_checkpoint
from agrl.rl.evaluation import run_episodes, summarise
from agrl.rl.models import logits_network, make_actor, make_critic


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


def distill(
    teacher: str | Path, destination: str | Path, *, observation: str = "absolute", rounds: int = 4,
    envs: int = 2048, epochs: int = 8, minibatch: int = 4096, learning_rate: float = 1e-3, epsilon: float = 0.1,
    evaluation_episodes: int = 1000, seed: int = 0, compile: bool = True, log=print,
) -> dict:
    """Write the student checkpoint to ``destination``; return its summary (agreement, evaluation on
    ``evaluation_episodes`` episodes of the teacher's task from seed ``seed + 1_000_003``). ``compile`` fuses the
    simulator (as training does)."""
    if rounds < 1 or envs < 1 or epochs < 1:
        raise ConfigError(f"rounds={rounds}, envs={envs}, epochs={epochs} are not allowed: each >= 1")
    path = resolve_checkpoint_path(teacher)
    payload = load_checkpoint(path, required=("actor", "critic", "config"))
    saved = payload["config"]
    agent = saved_agent_config(saved)
    torch.manual_seed(seed)
    teacher_actor = make_actor(agent.actor_hidden, agent.activation, observation=agent.observation)
    teacher_critic = make_critic(agent.critic_hidden, agent.activation, observation=agent.observation)
    load_module_state(teacher_actor, payload["actor"], path, "actor")
    load_module_state(teacher_critic, payload["critic"], path, "critic")
    student_actor = make_actor(agent.actor_hidden, agent.activation, observation=observation)
    student_critic = make_critic(agent.critic_hidden, agent.activation, observation=observation)
    params = saved_guidance_parameters(saved, compile=compile)
    simulation = params.simulation
    teacher_input, student_input = observation_function(agent.observation), observation_function(observation)

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
            target_value.append(teacher_critic.module(teacher_obs))
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

    evaluation_env = GuidanceEnv(dataclasses.replace(params, compile=False), num_envs=evaluation_episodes,
                                 seed=seed + 1_000_003, observation=observation)
    summary = {"distilled_from": str(path), "observation": observation, "rounds": rounds, "states": len(observations),
               "agreement": agreement,
               "evaluation": summarise(run_episodes(evaluation_env, student_actor.eval()))}
    config = {**saved, "agent": {**saved["agent"], "observation": observation}}
    save_checkpoint({"actor": student_actor.state_dict(), "critic": student_critic.state_dict(), "config": config,
                     "exported_from": str(path), "distillation": summary}, destination)
    return summary
