"""``method=pretrained``: Z starts from the baseline B's actor and critic, then trains on the task with plain PPO
(the paper's "pre-trained algorithm", its reference 18)."""

from __future__ import annotations

from dataclasses import dataclass

from agrl.config import MethodConfig, require_baseline
from agrl.rl.methods.from_baseline import FromBaseline


@dataclass
class PretrainedConfig(MethodConfig):
    def __post_init__(self) -> None:
        require_baseline(self)


class Pretrained(FromBaseline):
    config_class = PretrainedConfig
