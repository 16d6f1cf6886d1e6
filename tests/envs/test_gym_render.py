"""Rendering the gymnasium env: rgb_array frames, RecordVideo, SB3's render_mode default, "human" without a display."""

from __future__ import annotations

import warnings

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from matplotlib.colors import to_rgb

from agrl.core.termination import Outcome
from agrl.envs.gym import ENV_ID, GuidanceGymEnv
from agrl.plots import OUTCOME_COLOURS


def _pixels_of(frame: np.ndarray, colour: str, tolerance: int = 12) -> int:
    """Pixels of ``frame`` within ``tolerance`` (per channel) of the matplotlib colour ``colour``."""
    target = np.array([round(255 * channel) for channel in to_rgb(colour)])
    return int((np.abs(frame.astype(int) - target).max(axis=-1) <= tolerance).sum())


def test_rgb_array_frames_show_the_episode_and_its_outcome():
    env = gymnasium.make(ENV_ID, task="fixed", reward="none", render_mode="rgb_array")
    assert env.metadata["render_fps"] > 0
    seed = next(s for s in range(100) if env.reset(seed=s)[1]["aircraft_state"][2] < 1_200.0)  # low start
    env.reset(seed=seed)
    first = env.render()
    assert first.shape == (450, 800, 3) and first.dtype == np.uint8
    red = OUTCOME_COLOURS[Outcome.OUT_OF_AIRSPACE]
    legend_red = _pixels_of(first, red)  # the legend's "out of airspace" line; no path is red yet
    for _ in range(12):
        _, _, terminated, _, info = env.step(6)  # push over into the ground
        if terminated:
            break
    assert info["outcome"] == "out_of_airspace"
    last = env.render()
    assert last.shape == first.shape and not np.array_equal(first, last)
    assert _pixels_of(last, red) > legend_red + 50  # the aircraft's path is drawn in the outcome's colour
    env.close()


def test_env_checker_with_rendering():
    env = gymnasium.make(ENV_ID, task="uniform", render_mode="rgb_array", max_decisions=3).unwrapped
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(env)


def test_record_video_writes_a_video(tmp_path):
    env = gymnasium.make(ENV_ID, task="fixed", max_decisions=3, render_mode="rgb_array")
    env = gymnasium.wrappers.RecordVideo(env, str(tmp_path / "videos"), episode_trigger=lambda episode: True,
                                         disable_logger=True)
    env.reset(seed=0)
    terminated = False
    while not terminated:
        _, _, terminated, _, _ = env.step(0)
    env.close()
    videos = list((tmp_path / "videos").glob("*.mp4"))
    assert len(videos) == 1 and videos[0].stat().st_size > 1_000


def test_stable_baselines3_style_construction():
    """SB3's make_vec_env calls gymnasium.make(env_id, render_mode="rgb_array") by default."""
    env = gymnasium.make(ENV_ID, render_mode="rgb_array")
    assert env.render_mode == "rgb_array"
    env.reset(seed=0)
    assert env.render().shape == (450, 800, 3)


def test_human_mode_is_listed_only_with_a_display():
    """gymnasium's checker tries every listed mode, so a headless machine lists rgb_array only."""
    import os
    import sys

    headless = sys.platform not in ("darwin", "win32") and not (os.environ.get("DISPLAY")
                                                                or os.environ.get("WAYLAND_DISPLAY"))
    assert GuidanceGymEnv.metadata["render_modes"] == (["rgb_array"] if headless else ["rgb_array", "human"])


def test_human_mode_without_a_display_fails_clearly(monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setattr("sys.platform", "linux")
    with pytest.raises(ValueError, match="render_mode='human' is not allowed: 'human' needs a display"):
        GuidanceGymEnv(render_mode="human")
    with pytest.raises(ValueError, match="render_mode='video' is not allowed: None, 'rgb_array' or 'human'"):
        GuidanceGymEnv(render_mode="video")
    assert GuidanceGymEnv().render() is None  # no render mode: nothing to render
