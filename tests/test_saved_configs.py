"""Saved configs written before each value took its core record field's name (reward c1..c8, the flat simulation
keys) are read with today's names: :func:`agrl.config.upgraded_config`, wherever a saved config is read."""

from __future__ import annotations

import copy
import dataclasses

import pytest
import torch
from omegaconf import OmegaConf

from agrl.baselines import SHIPPED_AGENTS
from agrl.config import RENAMED_KEYS, guidance_parameters, saved_guidance_parameters, upgraded_config
from agrl.rl.checkpoint import load_checkpoint, save_checkpoint


def _select(config: dict, dotted: str):
    for key in dotted.split("."):
        if not isinstance(config, dict) or key not in config:
            return None
        config = config[key]
    return config


def _downgraded(config: dict) -> dict:
    """``config`` as a checkpoint written before the renaming held it (the inverse of :data:`RENAMED_KEYS`)."""
    old = upgraded_config(config)  # a copy
    for old_key, new_key in RENAMED_KEYS.items():
        *path, leaf = new_key.split(".")
        value = _select(old, ".".join(path)).pop(leaf)
        *old_path, old_leaf = old_key.split(".")
        _select(old, ".".join(old_path))[old_leaf] = value
    for section in ("tolerance", "limits"):  # emptied by the moves
        assert old["simulation"].pop(section) == {}
    return old


def _today(*overrides: str) -> dict:
    from agrl.config import compose_config

    return OmegaConf.to_container(compose_config(*overrides), resolve=True)


def test_the_shipped_files_hold_the_old_keys_and_upgrade_to_the_composed_ones():
    saved = torch.load(SHIPPED_AGENTS["baseline-two-stage"].file, weights_only=True)["config"]
    assert "c1" in saved["reward"] and "distance_tolerance" in saved["simulation"]  # what this upgrade is for
    upgraded = upgraded_config(saved)
    today = _today("+experiment=switch_finetune", "method.baseline=x")
    for section in ("task", "reward", "simulation"):
        assert upgraded[section] == today[section], section
    assert saved["reward"]["c1"] == 20.0  # the input is not changed


def test_an_upgrade_moves_every_renamed_key_and_nothing_else():
    today = _today("task=curved", "reward=both")
    old = _downgraded(today)
    assert old != today and set(old["reward"]) > {"c1", "c8"}
    assert upgraded_config(old) == today
    assert upgraded_config(today) == today  # today's keys: unchanged


@pytest.mark.parametrize("compile_loss", [True, False])
def test_a_config_saved_before_the_entropy_draw_option_gets_what_its_loss_did(compile_loss):
    """TorchRL's compiled loss drew a Monte-Carlo entropy estimate before ``ppo.compiled_entropy_draw`` existed: a
    compiled run resumed from then goes on drawing it (an eager loss never draws, whatever the option)."""
    today = _today(f"ppo.compile_loss={str(compile_loss).lower()}")
    assert today["ppo"]["compiled_entropy_draw"] is False  # the default
    old = copy.deepcopy(today)
    del old["ppo"]["compiled_entropy_draw"]
    assert upgraded_config(old)["ppo"]["compiled_entropy_draw"] is compile_loss
    assert upgraded_config(today) == today  # saved with the option: kept as it is
    drawing = _today("ppo.compiled_entropy_draw=true")
    assert upgraded_config(drawing) == drawing


def test_an_old_checkpoint_reads_as_today_s_and_gives_the_same_records(tmp_path):
    today = _today("task=uniform", "speed=20")
    path = save_checkpoint({"actor": {}, "config": _downgraded(today)}, tmp_path / "old.pt")
    assert load_checkpoint(path)["config"] == today  # evaluate, guide, resume and method.baseline read it so
    expected = guidance_parameters("task=uniform", "speed=20")
    assert saved_guidance_parameters(_downgraded(today), compile=False) == expected
    assert dataclasses.replace(saved_guidance_parameters(today), compile=False) == expected


def test_an_old_guide_export_s_limits_in_radians_still_load(tmp_path):
    """ONNX and torch.export files written before the flight-path limit was kept in degrees hold it in radians."""
    import json
    import math

    from agrl.guide import _from_metadata

    airspace = {"x_min": -1.0, "x_max": 1.0, "y_min": -1.0, "y_max": 1.0, "z_min": 0.0, "z_max": 1.0}
    old = json.dumps({"airspace": airspace,
                      "limits": {"min_speed": 100.0, "max_speed": 250.0, "max_flight_path_angle": math.radians(30.0)}})
    _, limits, _, actions = _from_metadata(old, tmp_path / "old.onnx")
    assert limits.max_flight_path_angle == math.radians(30.0)  # the radians the export was made with, exactly
    assert abs(limits.max_flight_path_angle_deg - 30.0) < 1e-12
    assert not actions.holds_targets  # an export written before action sets existed flies the paper's maneuvers
