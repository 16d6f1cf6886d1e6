"""agrl/plots.py: trajectory figures as files and as (H, W, 3) uint8 arrays."""

from __future__ import annotations

import numpy as np
import torch
from matplotlib.colors import to_rgb
from PIL import Image

from agrl.core.termination import Outcome
from agrl.plots import OUTCOME_COLOURS, figure_to_array, plot_trajectories, trajectory_figure, trajectory_image
from agrl.rl.evaluation import EpisodeRecords


def _records() -> EpisodeRecords:
    """Two straight-line episodes: one success, one out of the airspace."""
    steps = torch.linspace(0, 1, 6)
    aircraft = torch.zeros(2, 6, 7)
    aircraft[0, :, 0], aircraft[0, :, 2] = -6_000 + 6_000 * steps, 2_000 - 2_000 * steps
    aircraft[1, :, 1], aircraft[1, :, 2] = 11_000 * steps, 3_000.0
    destination = torch.zeros(2, 6, 4)
    return EpisodeRecords(
        initial_aircraft_state=aircraft[:, 0],
        outcome=torch.tensor([int(Outcome.SUCCESS), int(Outcome.OUT_OF_AIRSPACE)]),
        decisions=torch.tensor([5, 5]), instructions=torch.tensor([0, 0]), episode_return=torch.zeros(2),
        final_distance=torch.zeros(2), trajectory_aircraft=aircraft, trajectory_destination=destination,
    )


def _pixels_of(image: np.ndarray, colour: str, tolerance: int = 12) -> int:
    target = np.array([round(255 * channel) for channel in to_rgb(colour)])
    return int((np.abs(image.astype(int) - target).max(axis=-1) <= tolerance).sum())


def test_trajectory_image_is_the_saved_figure(tmp_path, paper_parameters):
    airspace = paper_parameters.simulation.airspace
    image = trajectory_image(_records(), airspace, title="two episodes")
    assert image.ndim == 3 and image.shape[2] == 3 and image.dtype == np.uint8
    for outcome in (Outcome.SUCCESS, Outcome.OUT_OF_AIRSPACE):  # both paths drawn (beyond their legend lines)
        assert _pixels_of(image, OUTCOME_COLOURS[outcome]) > 100
    saved = np.asarray(Image.open(plot_trajectories(_records(), tmp_path / "t.png", airspace, title="two episodes")))
    assert saved.shape[2] in (3, 4) and saved.shape[0] > 100  # the file path still works


def test_figure_to_array_matches_the_canvas_size(paper_parameters):
    figure = trajectory_figure(_records(), paper_parameters.simulation.airspace)
    width, height = figure.canvas.get_width_height()
    image = figure_to_array(figure)
    assert image.shape == (height, width, 3)
    assert image.min() < 100 and image.max() == 255  # ink on a white background
