"""Aircraft guidance with deep reinforcement learning (policy reuse by destination position prediction).

Importing ``agrl`` is light (no torch): it only registers the gymnasium environment
``agrl/Guidance-v0`` (see :mod:`agrl.envs.gym`), which is built on first ``gymnasium.make``.
"""

from __future__ import annotations

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("agrl")
except PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0.0.0+unknown"

GYM_ENV_ID = "agrl/Guidance-v0"


def _register_gym_env() -> None:
    try:
        import gymnasium
    except ImportError:  # gymnasium is a dependency; without it there is nothing to register
        return
    if GYM_ENV_ID not in gymnasium.registry:  # importing twice (or reloading) must not fail
        # No PassiveEnvChecker (the test suite runs gymnasium's full check_env instead): in gymnasium 1.4 a first
        # reset that raises (bad options) leaves it holding None, and a later step then fails inside it.
        gymnasium.register(id=GYM_ENV_ID, entry_point="agrl.envs.gym:GuidanceGymEnv",
                           vector_entry_point="agrl.envs.gym_vector:GuidanceVectorEnv", disable_env_checker=True)


_register_gym_env()
