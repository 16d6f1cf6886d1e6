"""``method=scratch``: train Z from random weights (the paper's "training from scratch")."""

from __future__ import annotations

from agrl.config import MethodConfig
from agrl.rl.methods.base import Method


class Scratch(Method):
    """Random starting weights; nothing added to PPO. ``method.baseline`` is accepted and unused, so a sweep over
    ``method=scratch,pretrained,reuse`` can set it once."""

    config_class = MethodConfig

