"""The start-box curriculum (a training aid, not in the paper; see docs/training.md).

Training episodes first start in a box shrunk towards the destination's start
(``curriculum.initial_scale`` of the full box); each iteration whose training
success rate reaches ``curriculum.promotion_success`` grows it by
``curriculum.scale_step``, up to the full box. Evaluation always uses the full box.
The scale itself is part of the trainer's counters, so it is checkpointed and resumed.
"""

from __future__ import annotations

from agrl.core.initial_states import InitialStateDistribution, scale_distribution
from agrl.core.parameters import GuidanceParameters


def promoted_scale(scale: float, success_rate: float | None, scale_step: float, promotion_success: float) -> float:
    """The next iteration's scale: one step larger (capped at 1) if this iteration's success earned it."""
    if scale < 1.0 and success_rate is not None and success_rate >= promotion_success:
        return min(1.0, round(scale + scale_step, 6))
    return scale


def start_distribution(params: GuidanceParameters, scale: float) -> InitialStateDistribution:
    """The training start box at ``scale``: shrunk about the destination's start, never solved at the start."""
    return scale_distribution(params.initial_state, min(1.0, scale), tuple(params.destination.start[:3]),
                              success_distance=params.simulation.tolerance.distance)
