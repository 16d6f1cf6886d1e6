"""Training methods as plug-ins: a method registered from outside agrl trains through the trainer's hooks."""

from __future__ import annotations

from dataclasses import dataclass

import pytest
import torch

from agrl.config import ConfigError, MethodConfig, method_class, method_names, register_method, require
from agrl.report import read_metrics
from agrl.rl.checkpoint import load_checkpoint
from agrl.rl.methods import Method
from agrl.rl.trainer import Trainer

pytestmark = pytest.mark.usefixtures("torch_one_thread")


@dataclass
class HalvedStartConfig(MethodConfig):
    start_scale: float = 0.5  # the actor's starting weights are multiplied by this

    def __post_init__(self) -> None:
        require(0 < self.start_scale <= 1, "method.start_scale", self.start_scale, "(0, 1]")


class HalvedStart(Method):
    """A toy method: Z starts from scaled random weights, stores every other collected row, and counts the rows
    it stored (a dashboard scalar and checkpoint state)."""

    config_class = HalvedStartConfig

    def __init__(self, config: HalvedStartConfig):
        super().__init__(config)
        self.rows_stored = 0

    def start(self, trainer) -> None:
        with torch.no_grad():
            for parameter in trainer.actor.parameters():
                parameter.mul_(self.config.start_scale)

    def buffer_rows(self, rows, update_fields):
        kept = rows[::2].select(*update_fields)
        self.rows_stored += kept.numel()
        return kept

    def iteration_metrics(self, trainer, fill_seconds: float) -> dict[str, float]:
        return {"toy/rows_stored": float(self.rows_stored), "toy/buffer_rows": float(len(trainer.buffer))}

    def state_dict(self) -> dict:
        return {"rows_stored": self.rows_stored}

    def load_state_dict(self, state: dict) -> None:
        self.rows_stored = state["rows_stored"]


register_method("halved_start", HalvedStart, defaults={"use_curriculum": False, "start_scale": 0.5})


def test_the_builtin_methods_and_a_registered_one_are_listed():
    assert {"scratch", "pretrained", "reuse", "halved_start"} <= set(method_names())
    assert method_class("halved_start") is HalvedStart


def test_an_unregistered_method_is_one_line_naming_the_registered_ones():
    with pytest.raises(ConfigError, match=r"^method='nope' is not allowed: one of .*halved_start.*reuse"):
        method_class("nope")


def test_a_registered_method_trains_through_its_hooks_and_resumes(tmp_path, compose_train, tiny_args):
    config = compose_train(*tiny_args({"ppo.total_frames": 512}), "method=halved_start", "method.start_scale=0.25")
    assert isinstance(config.method, HalvedStartConfig) and config.method.start_scale == 0.25
    torch.manual_seed(config.seed)
    scratch = Trainer(compose_train(*tiny_args({"ppo.total_frames": 512})), tmp_path / "scratch")
    trainer = Trainer(config, tmp_path / "toy")
    for (name, toy), (_, plain) in zip(trainer.actor.state_dict().items(), scratch.actor.state_dict().items(),
                                       strict=True):
        torch.testing.assert_close(toy, 0.25 * plain, msg=name)  # the same seed: the start hook scaled them

    summary = trainer.train()
    assert summary["method"] == "halved_start" and summary["iterations"] == 1
    rows = read_metrics(tmp_path / "toy")
    stored = [row["toy/rows_stored"] for row in rows if "toy/rows_stored" in row]
    assert stored == [256.0] and [row["toy/buffer_rows"] for row in rows if "toy/buffer_rows" in row] == [256.0]
    saved = load_checkpoint(tmp_path / "toy" / "checkpoints" / "latest.pt")
    assert saved["method_state"] == {"rows_stored": 256}
    assert saved["config"]["method"] == {"name": "halved_start", "use_curriculum": False, "baseline": None,
                                         "start_scale": 0.25}

    resumed = Trainer(compose_train(*tiny_args({"ppo.total_frames": 1024}), "method=halved_start",
                                    "method.start_scale=0.25"), tmp_path / "toy", resume_payload=saved)
    assert resumed.method.rows_stored == 256
    resumed.train()
    assert resumed.method.rows_stored == 512


def test_a_registered_method_checks_its_own_values(compose_train, tiny_args):
    with pytest.raises(ConfigError, match=r"^method.start_scale=2.0 is not allowed: \(0, 1\]$"):
        compose_train(*tiny_args(), "method=halved_start", "method.start_scale=2")
