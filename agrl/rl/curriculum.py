"""The start-box curriculum (a training aid, not in the paper; see docs/training.md).

Training episodes first start in a box shrunk towards the destination's start
(``curriculum.initial_scale`` of the full box); each iteration whose training
success rate reaches ``curriculum.promotion_success`` grows it by
``curriculum.scale_step``, up to the full box. Evaluation always uses the full box.
The scale itself is part of the trainer's counters, so it is checkpointed and resumed.

With ``ppo.collector_workers > 1`` the training envs live in TorchRL's worker processes, out of
the trainer's reach: each worker builds a :class:`SharedScaleGuidanceEnv`, which reads the scale
from a one-number tensor in shared memory at every reset (given as ``create_env_kwargs``, see
:func:`shared_scale`), and the trainer writes a promotion into that tensor before it asks for the
next batch (:class:`~torchrl.collectors.MultiSyncCollector` steps no env between batches), so the
next batch's new episodes start in the new box, as they do in one process.
"""

from __future__ import annotations

import torch

from agrl.core.initial_states import InitialStateDistribution, scale_distribution
from agrl.core.parameters import GuidanceParameters
from agrl.envs.guidance import GuidanceEnv


def promoted_scale(scale: float, success_rate: float | None, scale_step: float, promotion_success: float) -> float:
    """The next iteration's scale: one step larger (capped at 1) if this iteration's success earned it."""
    if scale < 1.0 and success_rate is not None and success_rate >= promotion_success:
        return min(1.0, round(scale + scale_step, 6))
    return scale


def start_distribution(params: GuidanceParameters, scale: float) -> InitialStateDistribution:
    """The training start box at ``scale``: shrunk about the destination's start, never solved at the start."""
    return scale_distribution(params.initial_state, min(1.0, scale), tuple(params.destination.start[:3]),
                              success_distance=params.simulation.tolerance.distance)


def shared_scale(scale: float) -> torch.Tensor:
    """A float64 scalar tensor holding ``scale`` in shared memory. Handed to a worker process as a process
    argument (pickled by ``torch.multiprocessing``, with any start method) it stays one storage, so a write here is
    read there; a collector's ``create_env_kwargs`` go that way. A copy, not a share, if it travels inside a
    cloudpickled object such as TorchRL's wrapper of an env factory."""
    return torch.tensor(scale, dtype=torch.float64).share_memory_()


class SharedScaleGuidanceEnv(GuidanceEnv):
    """A :class:`GuidanceEnv` whose new episodes start in ``start_distribution(params, scale)``, with ``scale``
    read from the tensor ``scale`` (see :func:`shared_scale`) at each reset."""

    def __init__(self, params: GuidanceParameters, scale: torch.Tensor, **kwargs):
        super().__init__(params, **kwargs)
        self._full_box_params = params  # the full start box: each scale shrinks this one
        self._scale = scale
        self._applied_scale: float | None = None
        self._follow_scale()

    def _follow_scale(self) -> None:
        scale = float(self._scale)
        if scale != self._applied_scale:
            self.set_initial_state_distribution(start_distribution(self._full_box_params, scale))
            self._applied_scale = scale

    def draw_starts(self, count: int) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
        self._follow_scale()
        return super().draw_starts(count)
