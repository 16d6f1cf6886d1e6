"""What the methods that start from a trained agent B share: loading B, and Z's starting weights from it."""

from __future__ import annotations

import dataclasses
import logging
from pathlib import Path
from typing import TYPE_CHECKING, Any

import torch
from torchrl.modules import ProbabilisticActor, ValueOperator

from agrl.config import LEGACY_ACTIONS, AgentConfig, saved_guidance_parameters, to_guidance_parameters
from agrl.core.observation import LEGACY_OBSERVATION
from agrl.envs.guidance import NUM_ACTIONS
from agrl.rl.checkpoint import CheckpointError, load_checkpoint, load_module_state, resolve_checkpoint_path
from agrl.rl.methods.base import Method
from agrl.rl.models import make_actor, make_agent

if TYPE_CHECKING:
    from agrl.rl.trainer import Trainer

log = logging.getLogger("agrl.train")

#: The ``agent`` keys that shape the networks (a Z started from B's weights has B's).
NETWORK_KEYS = ("actor_hidden", "critic_hidden", "activation")


def _load(reference: str) -> tuple[Path, dict]:
    """B's checkpoint file and payload (``method.baseline``: a shipped agent's name, a file or a run directory)."""
    try:
        path = resolve_checkpoint_path(reference)
        return path, load_checkpoint(path, required=("actor", "critic"))
    except CheckpointError as error:
        raise CheckpointError(f"method.baseline: {error}") from None


def load_baseline(cfg: Any, baseline: tuple[Path, dict], device: torch.device | str, actor: ProbabilisticActor,
                  critic: ValueOperator, start_from_it: bool):
    """``(B, path, B's observation)`` from ``baseline``, the file and payload ``cfg.method.baseline`` names: B is the
    frozen baseline actor. With ``start_from_it``, Z's ``actor`` and ``critic`` start from B's weights. A file that
    does not fit (another action set or target table, another observation, other network shapes) is a
    :class:`CheckpointError` naming it."""
    path, payload = baseline
    saved = payload.get("config", {})
    baseline_agent = saved.get("agent", {})
    observation = baseline_agent.get("observation", LEGACY_OBSERVATION)
    actions = saved.get("actions", LEGACY_ACTIONS)["name"]
    if actions != cfg.actions.name:
        raise CheckpointError(f"{path}: actions={cfg.actions.name} is not allowed with this baseline: it was trained "
                              f"with actions={actions}; train Z with the same")
    # A baseline holding targets counts its actions from its own airspace and limits (its saved config); its action
    # indices mean what they mean in Z's env only if the two target tables are the same.
    params = saved_guidance_parameters(saved) if actions != LEGACY_ACTIONS["name"] else None
    if params is not None:
        own = to_guidance_parameters(cfg.task, cfg.reward, cfg.simulation, actions=cfg.actions)
        tables = [record.actions.target_table(record.simulation.airspace, record.simulation.limits)
                  for record in (own, params)]
        if not all(torch.equal(mine, theirs) for mine, theirs in zip(*tables, strict=True)):
            raise CheckpointError(f"{path}: this run's target table is not allowed with this baseline: B's (its "
                                  "actions.headings, altitude_step, lowest_altitude, cruise_speed, the airspace's "
                                  "heights and the speed limits) differs; train Z with the same")
    if start_from_it:
        if observation != cfg.agent.observation:
            raise CheckpointError(
                f"{path}: agent.observation={cfg.agent.observation} is not allowed when starting from this "
                f"baseline: it was trained with observation={observation}; train Z with the same"
            )
        load_module_state(actor, payload["actor"], path, "actor")
        load_module_state(critic, payload["critic"], path, "critic")
    holds_targets = params is not None and params.actions.holds_targets
    baseline = make_actor(baseline_agent.get("actor_hidden", cfg.agent.actor_hidden),
                          baseline_agent.get("activation", cfg.agent.activation), device, observation,
                          params.num_actions if params is not None else NUM_ACTIONS, holds_targets)
    load_module_state(baseline, payload["actor"], path, "baseline actor")
    return baseline.eval().requires_grad_(False), path, observation


class FromBaseline(Method):
    """A method given a trained agent B (``method.baseline``): B is loaded, frozen, at the start of the run
    (``self.baseline_actor``, ``self.baseline_observation``); Z starts from B's weights if
    :meth:`starts_from_baseline`."""

    baseline_actor: ProbabilisticActor | None = None
    _baseline_file: tuple[Path, dict] | None = None

    def starts_from_baseline(self) -> bool:
        return True

    def baseline_file(self) -> tuple[Path, dict]:
        """B's checkpoint file and payload, read once (an unreadable one is a one-line :class:`CheckpointError`)."""
        if self._baseline_file is None:
            self._baseline_file = _load(self.config.baseline)
        return self._baseline_file

    @classmethod
    def check_inputs(cls, train_config: Any) -> None:
        params = to_guidance_parameters(train_config.task, train_config.reward, train_config.simulation,
                                        actions=train_config.actions)
        method = cls(train_config.method)
        load_baseline(train_config, method.baseline_file(), "cpu",
                      *make_agent(method.agent_config(train_config), params, "cpu"), method.starts_from_baseline())

    def agent_config(self, train_config: Any) -> AgentConfig:
        """B's layer widths and activation when Z starts from B's weights (:meth:`starts_from_baseline`): Z can
        only be B's networks then, whatever ``agent`` says (a difference is logged); else ``agent``'s."""
        if not self.starts_from_baseline():
            return train_config.agent
        saved = self.baseline_file()[1].get("config", {}).get("agent", {})  # a file without one: agent's widths
        networks = dataclasses.replace(train_config.agent, **{key: saved[key] for key in NETWORK_KEYS if key in saved})
        if networks != train_config.agent:
            given = ", ".join(f"{key}={getattr(train_config.agent, key)}" for key in NETWORK_KEYS)
            log.info("method=%s: Z starts from B's weights, so it has B's networks (%s), not agent's (%s)",
                     self.config.name, ", ".join(f"{key}={getattr(networks, key)}" for key in NETWORK_KEYS), given)
        return networks

    def start(self, trainer: Trainer) -> None:
        self.baseline_actor, self.baseline_path, self.baseline_observation = load_baseline(
            trainer.cfg, self.baseline_file(), trainer.device, trainer.actor, trainer.critic,
            self.starts_from_baseline())
