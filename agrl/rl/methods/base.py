"""The interface between the trainer and a training method (scratch, pretrained, policy reuse, or your own).

The trainer (:class:`agrl.rl.trainer.Trainer`) names no method: it builds the one ``method.name`` picks from
the registry (:func:`agrl.config.register_method`) and calls the hooks below at fixed points of a run. Each
default does nothing, so a method overrides only what it changes. A method is one module: its config schema (a
:class:`~agrl.config.MethodConfig` subclass, ``config_class``) beside the class. ``docs/training.md``, "Adding a
method", has a complete example.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, ClassVar

from tensordict import TensorDictBase
from torchrl.envs import Transform

from agrl.config import AgentConfig, MethodConfig

if TYPE_CHECKING:
    from agrl.rl.trainer import Trainer


class Method:
    """One way to train the agent Z. The hooks, in the order a run calls them:

    1. :meth:`check_inputs` (class method): before anything is written, read the files the run will read.
    2. :meth:`agent_config`: the networks Z has (the ``agent`` section, or what the method's starting point needs).
    3. :meth:`start`: after Z's actor and critic exist, before the optimiser: starting weights, frozen helpers.
    4. :meth:`storage_rows`, :meth:`buffer_transform`: the replay buffer's size and its transform.
    5. per iteration: :meth:`buffer_rows` (what of the batch the buffer stores), :meth:`max_updates`, then
       :meth:`iteration_metrics` (extra dashboard scalars).
    6. checkpoints: :meth:`state_dict` / :meth:`load_state_dict` (extra state for exact resume).
    """

    config_class: ClassVar[type[MethodConfig]] = MethodConfig
    #: Whether each collected row carries its episode's id (TorchRL's ``("collector", "traj_ids")``): bookkeeping
    #: on every decision the collector does only for a method that reads it.
    episode_ids: ClassVar[bool] = False

    def __init__(self, config: MethodConfig):
        self.config = config

    @classmethod
    def check_inputs(cls, train_config: Any) -> None:
        """Read the files a run of this method will read (a baseline checkpoint) as it will, raising a one-line
        :class:`~agrl.rl.checkpoint.CheckpointError` or :class:`~agrl.config.ConfigError` if one does not fit.
        Runs before Hydra writes anything (``agrl.cli.run_checked``)."""

    def agent_config(self, train_config: Any) -> AgentConfig:
        """Z's networks and observation (the run records them in its checkpoints): ``train_config.agent``."""
        return train_config.agent

    def start(self, trainer: Trainer) -> None:
        """Prepare the run: ``trainer.actor`` and ``trainer.critic`` exist (their starting weights may be loaded
        here), the PPO loss and optimiser do not yet."""

    def storage_rows(self, frames_per_batch: int) -> int:
        """Rows the replay buffer holds: one collected batch unless the transform adds rows."""
        return frames_per_batch

    def buffer_transform(self, trainer: Trainer) -> Transform | None:
        """The replay buffer's transform (it sees each collected batch on its way in), or None."""
        return None

    def buffer_rows(self, rows: TensorDictBase, update_fields: list) -> TensorDictBase:
        """The flat collected rows as the buffer stores them: by default only the fields the update reads."""
        return rows.select(*update_fields)

    def max_updates(self, frames_per_batch: int, epochs: int, minibatch_size: int) -> int | None:
        """The most minibatch steps in one update, or None: ``epochs`` passes over the buffer's rows."""
        return None

    def iteration_metrics(self, trainer: Trainer, fill_seconds: float) -> dict[str, float]:
        """Extra scalars for this iteration's dashboard; ``fill_seconds``: the time the buffer took to fill."""
        return {}

    def state_dict(self) -> dict | None:
        """Extra state a checkpoint keeps for exact resume (tensors and plain data), or None."""
        return None

    def load_state_dict(self, state: dict) -> None:
        """Restore what :meth:`state_dict` returned."""
