"""Hydra composition of conf/ and validation by agrl.config.load_config."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from hydra import compose, initialize_config_dir
from hydra.errors import ConfigCompositionException, MissingConfigException
from omegaconf.errors import ValidationError

from agrl.config import ConfigError, TaskConfig, load_config, task_label, to_guidance_parameters
from agrl.envs import MotionKind

CONFIG_DIR = str((Path(__file__).resolve().parent.parent / "conf").resolve())


def compose_config(*overrides: str):
    with initialize_config_dir(config_dir=CONFIG_DIR, version_base="1.3"):
        return compose(config_name="config", overrides=list(overrides))


def load(*overrides: str):
    return load_config(compose_config(*overrides))


def test_defaults_load():
    cfg = load()
    assert isinstance(cfg.task, TaskConfig)
    assert cfg.task.name == "fixed"
    assert cfg.simulation.integration_step == pytest.approx(0.02)
    assert cfg.simulation.decision_period == pytest.approx(3.0)


def test_uniform_speed_flows_into_task():
    cfg = load("task=uniform", "speed=50")
    assert cfg.task.name == "uniform"
    assert cfg.task.speed == 50.0
    assert load("task=uniform", "speed=10").task.speed == 10.0


def test_curved_radius_flows_into_task():
    cfg = load("task=curved", "radius=500")
    assert cfg.task.name == "curved"
    assert cfg.task.radius == 500.0
    assert cfg.task.speed == 20.0  # the paper's curved-motion speed
    params = to_guidance_parameters(cfg.task, cfg.reward, cfg.simulation, compile=False)
    assert params.destination.kind is MotionKind.CURVED
    assert params.destination.radius == 500.0
    assert params.compile is False
    assert params.simulation.tolerance.heading == pytest.approx(
        math.radians(cfg.simulation.heading_tolerance_deg)
    )


def test_switch_cost_is_off_in_the_papers_variants_and_reaches_the_env():
    for name in ("none", "continuous", "position", "both"):
        cfg = load(f"reward={name}")
        assert to_guidance_parameters(cfg.task, cfg.reward, cfg.simulation, compile=False).reward.switch_cost == 0.0
    cfg = load("reward=switch", "reward.switch_cost=0.7")
    params = to_guidance_parameters(cfg.task, cfg.reward, cfg.simulation, compile=False).reward
    assert (params.switch_cost, params.use_continuous_action, params.use_position) == (0.7, True, True)


def test_unknown_task_names_the_value():
    with pytest.raises(MissingConfigException) as info:
        load("task=bogus")
    lines = str(info.value).splitlines()
    assert lines[0] == "In 'config': Could not find 'task/bogus'"
    assert lines[2:7] == ["Available options in 'task':", "\tcurved", "\tfixed", "\tirregular", "\tuniform"]


def test_unknown_task_name_in_group_is_a_config_error():
    with pytest.raises(ConfigError, match="bogus"):
        load("task=uniform", "speed=50", "task.name=bogus")


def test_negative_uniform_speed_fails():
    with pytest.raises(ConfigError, match=r"speed=-5") as info:
        load("task=uniform", "speed=-5")
    assert "\n" not in str(info.value)


def test_zero_curved_radius_fails():
    with pytest.raises(ConfigError, match=r"radius=0") as info:
        load("task=curved", "radius=0")
    assert "\n" not in str(info.value)


def test_wrong_type_names_the_value():
    with pytest.raises(ConfigCompositionException, match=r"^Error merging override speed=abc$") as info:
        load("task=uniform", "speed=abc")
    cause = info.value.__cause__
    assert isinstance(cause, ValidationError)
    assert str(cause).splitlines()[0] == "Value 'abc' of type 'str' could not be converted to Float"


@pytest.mark.parametrize(
    "overrides,named",
    [
        (("reward.gamma=1.5",), "reward.gamma"),
        (("reward=switch", "reward.switch_cost=-0.1"), "reward.switch_cost"),
        (("simulation.decision_period=3.01",), "simulation.decision_period"),
        (("simulation.min_speed=300",), "simulation.min_speed"),
        (("simulation.initial_state.x_range=[-20000,0]",), "simulation.initial_state.x_range"),
        (("ppo.minibatch_size=100000000",), "ppo.minibatch_size"),
        (("threads=0",), "threads=0"),
        (("task=irregular", "task.change_probability=2"), "task.change_probability"),
        (("method=pretrained", "method.start_from_baseline=true"), "method.start_from_baseline"),
        (("method.start_from_baseline=true",), "method.start_from_baseline"),
        (("simulation.initial_state.min_horizontal_distance=900",), "simulation.initial_state.min_horizontal_distance"),
    ],
)
def test_config_errors_are_one_line_and_name_the_key(overrides, named):
    with pytest.raises(ConfigError) as info:
        load(*overrides)
    message = str(info.value)
    assert named in message
    assert "\n" not in message


def test_task_label_names_the_motion_parameters():
    assert task_label(TaskConfig(name="uniform", speed=50.0)) == "uniform 50 m/s"
    assert task_label(TaskConfig(name="curved", speed=20.0, radius=500.0)) == "curved 20 m/s, radius 500 m"
    assert task_label(TaskConfig(name="fixed")) == "fixed"


def test_unavailable_cuda_device_is_one_line_naming_what_is_available():
    import torch

    count = torch.cuda.device_count() if torch.cuda.is_available() else 0
    missing = f"cuda:{count}"  # one past the last device this machine has (cuda:0 on a CPU-only build)
    available = ", ".join(["cpu"] + [f"cuda:{index}" for index in range(count)])
    with pytest.raises(ConfigError) as info:
        load(f"device={missing}")
    expected = f"device={missing!r} is not allowed: this machine has {available} (torch {torch.__version__})"
    assert str(info.value) == expected


@pytest.mark.parametrize("device", ["gpu", "cuda:x", "cuda0"])
def test_malformed_device_is_refused(device):
    with pytest.raises(ConfigError, match=rf"device='{device}' is not allowed: cpu, cuda or cuda:N"):
        load(f"device={device}")
