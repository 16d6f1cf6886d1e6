"""Training methods: scratch, pretrained and the paper's policy reuse, each one module with its config schema,
behind the hooks of :class:`Method` that the trainer calls. Register another with
:func:`agrl.config.register_method` (``docs/training.md``, "Adding a method")."""

from agrl.config import register_method
from agrl.rl.methods.base import Method

__all__ = ["Method", "register_method"]
