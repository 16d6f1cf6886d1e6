"""TorchRL and gymnasium environments built on :mod:`agrl.core`."""

from agrl.core.parameters import DestinationMotion, GuidanceParameters, ManeuverLoadFactors, MotionKind
from agrl.envs.guidance import NUM_ACTIONS, GuidanceEnv

__all__ = [
    "NUM_ACTIONS",
    "DestinationMotion",
    "GuidanceEnv",
    "GuidanceParameters",
    "ManeuverLoadFactors",
    "MotionKind",
]
