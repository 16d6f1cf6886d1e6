"""TorchRL and gymnasium environments built on :mod:`agrl.core`."""

from agrl.envs.guidance import NUM_ACTIONS, GuidanceEnv
from agrl.envs.parameters import DestinationMotion, GuidanceParameters, ManeuverLoadFactors, MotionKind

__all__ = [
    "NUM_ACTIONS",
    "DestinationMotion",
    "GuidanceEnv",
    "GuidanceParameters",
    "ManeuverLoadFactors",
    "MotionKind",
]
