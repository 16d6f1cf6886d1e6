"""Figures: 3-D trajectories (the paper's Figures 6, 8, 10), success against wall time (Figures 5, 7, 9), and the
gymnasium environment's frames (the same trajectory drawing), all also as ``(H, W, 3)`` uint8 arrays."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files only; no display needed
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from agrl.core.termination import Airspace, Outcome  # noqa: E402

OUTCOME_COLOURS = {
    Outcome.SUCCESS: "tab:green",
    Outcome.OUT_OF_AIRSPACE: "tab:red",
    Outcome.BUDGET_EXHAUSTED: "tab:orange",
    Outcome.RUNNING: "tab:gray",
}

#: Episodes a trajectory figure draws by default (the first ones of an evaluation).
DRAWN_EPISODES = 10


def _draw_airspace_box(axes, airspace: Airspace) -> None:
    """The edges of equation 1's box, in km, and axis limits on it."""
    xs = (airspace.x_min / 1000, airspace.x_max / 1000)
    ys = (airspace.y_min / 1000, airspace.y_max / 1000)
    zs = (airspace.z_min / 1000, airspace.z_max / 1000)
    for y in ys:
        for z in zs:
            axes.plot(xs, (y, y), (z, z), color="0.8", linewidth=0.6)
    for x in xs:
        for z in zs:
            axes.plot((x, x), ys, (z, z), color="0.8", linewidth=0.6)
        for y in ys:
            axes.plot((x, x), (y, y), zs, color="0.8", linewidth=0.6)
    axes.set_xlim(*xs)
    axes.set_ylim(*ys)
    axes.set_zlim(*zs)
    axes.set_xlabel("x (km)")
    axes.set_ylabel("y (km)")
    axes.set_zlabel("z (km)")


def _draw_episode(axes, aircraft_m, destination_m, outcome: Outcome) -> None:
    """One episode: the aircraft's path (outcome colour, a dot at its start), the destination's track (black, a
    cross where it is now). ``aircraft_m`` and ``destination_m`` are ``(steps, >=3)`` positions in metres."""
    colour = OUTCOME_COLOURS[outcome]
    aircraft = [[float(value) / 1000.0 for value in row[:3]] for row in aircraft_m]
    destination = [[float(value) / 1000.0 for value in row[:3]] for row in destination_m]
    axes.plot(*zip(*aircraft, strict=True), color=colour, linewidth=1.2)
    axes.scatter(*aircraft[0], color=colour, marker="o", s=12)
    axes.plot(*zip(*destination, strict=True), color="black", linewidth=1.0)
    axes.scatter(*destination[-1], color="black", marker="x", s=20)


def _outcome_legend(axes) -> None:
    handles = [plt.Line2D([], [], color=c, label=o.name.lower().replace("_", " "))
               for o, c in OUTCOME_COLOURS.items() if o is not Outcome.RUNNING]
    handles.append(plt.Line2D([], [], color="black", label="destination"))
    axes.legend(handles=handles, loc="upper left", fontsize=8)


def trajectory_figure(records, airspace: Airspace, count: int = DRAWN_EPISODES, title: str = ""):
    """The figure of :func:`plot_trajectories` (a matplotlib ``Figure``; close it with ``plt.close``)."""
    if records.trajectory_aircraft is None:
        raise ValueError("records carry no trajectories: run_episodes(..., trajectories=<episodes>)")
    figure = plt.figure(figsize=(8, 6.5))
    axes = figure.add_subplot(projection="3d")
    count = min(count, records.trajectory_aircraft.shape[0])
    for index in range(count):
        length = int(records.decisions[index]) + 1
        _draw_episode(axes, records.trajectory_aircraft[index, :length].tolist(),
                      records.trajectory_destination[index, :length].tolist(), Outcome(int(records.outcome[index])))
    _draw_airspace_box(axes, airspace)
    _outcome_legend(axes)
    axes.set_title(title or f"{count} evaluation episodes")
    return figure


def plot_trajectories(records, path: str | Path, airspace: Airspace, count: int = DRAWN_EPISODES,
                      title: str = "") -> Path:
    """Aircraft paths (coloured by outcome) and destination paths (black) of the first ``count`` episodes, in km."""
    figure = trajectory_figure(records, airspace, count, title)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(path, dpi=120, bbox_inches="tight")
    plt.close(figure)
    return path


def figure_to_array(figure, close: bool = True) -> np.ndarray:
    """A matplotlib figure as an ``(H, W, 3)`` uint8 RGB image (e.g. for ``SummaryWriter.add_image(...,
    dataformats="HWC")``); closes the figure unless ``close=False``."""
    figure.canvas.draw()
    image = np.asarray(figure.canvas.buffer_rgba())[..., :3].copy()
    if close:
        plt.close(figure)
    return image


def trajectory_image(records, airspace: Airspace, count: int = DRAWN_EPISODES, title: str = "") -> np.ndarray:
    """:func:`plot_trajectories`' figure as an ``(H, W, 3)`` uint8 array (no file written)."""
    return figure_to_array(trajectory_figure(records, airspace, count, title))


def episode_frame_figure(aircraft_path, destination_path, outcome: Outcome, airspace: Airspace, title: str = "",
                         size_inches: tuple[float, float] = (8.0, 4.5), dpi: int = 100):
    """One environment frame: the episode so far in 3-D (:func:`trajectory_figure`'s drawing) and a top view.

    ``aircraft_path`` / ``destination_path``: ``(decisions + 1, >=3)`` positions in metres; the aircraft is a
    triangle where it is now. The title carries ``title`` and the outcome.
    """
    figure = plt.figure(figsize=size_inches, dpi=dpi)
    grid = figure.add_gridspec(1, 2, width_ratios=(1.5, 1.0), left=0.0, right=0.97, bottom=0.1, top=0.9, wspace=0.3)
    axes = figure.add_subplot(grid[0], projection="3d")
    _draw_episode(axes, aircraft_path, destination_path, outcome)
    x, y, z = (float(value) / 1000.0 for value in aircraft_path[-1][:3])
    axes.scatter(x, y, z, color=OUTCOME_COLOURS[outcome], marker="^", s=30)
    _draw_airspace_box(axes, airspace)
    _outcome_legend(axes)
    top = figure.add_subplot(grid[1])
    colour = OUTCOME_COLOURS[outcome]
    top.plot([row[0] / 1000.0 for row in aircraft_path], [row[1] / 1000.0 for row in aircraft_path], color=colour)
    top.plot([row[0] / 1000.0 for row in destination_path], [row[1] / 1000.0 for row in destination_path],
             color="black")
    top.scatter(x, y, color=colour, marker="^", s=30)
    top.scatter(destination_path[-1][0] / 1000.0, destination_path[-1][1] / 1000.0, color="black", marker="x", s=20)
    top.set_xlim(airspace.x_min / 1000, airspace.x_max / 1000)
    top.set_ylim(airspace.y_min / 1000, airspace.y_max / 1000)
    top.set_aspect("equal")
    top.set_xlabel("x (km)")
    top.set_ylabel("y (km)")
    top.set_title(f"top view, altitude {z:.2f} km", fontsize=9)
    figure.suptitle(f"{title}  {outcome.name.lower().replace('_', ' ')}".strip(), fontsize=10)
    return figure


def episode_frame(aircraft_path, destination_path, outcome: Outcome, airspace: Airspace, title: str = "",
                  size_inches: tuple[float, float] = (8.0, 4.5), dpi: int = 100) -> np.ndarray:
    """:func:`episode_frame_figure` as an ``(H, W, 3)`` uint8 array (``H, W = dpi * size_inches``)."""
    return figure_to_array(episode_frame_figure(aircraft_path, destination_path, outcome, airspace, title,
                                                size_inches, dpi))


def plot_success_against_time(curves: Mapping[str, Sequence[list[dict]]], path: str | Path, title: str = "",
                              key: str = "eval/success_rate") -> Path:
    """Success against training wall time, one colour per label (the paper's Figures 5, 7 and 9).

    Large dots: ``key`` (by default the periodic evaluation over the full start box); thin line: the training
    success of each iteration (with the curriculum, scratch runs train on easier starts first).
    """
    figure, axes = plt.subplots(figsize=(7, 4.5))
    for colour, (label, runs) in enumerate(curves.items()):
        for number, rows in enumerate(runs):  # a run's rows: agrl.report.read_metrics
            train = [(row["wall_time"] / 60, row["train/success_rate"]) for row in rows
                     if row.get("train/success_rate") is not None]
            evaluated = [(row["wall_time"] / 60, row[key]) for row in rows if row.get(key) is not None]
            if train:
                axes.plot(*zip(*train, strict=True), color=f"C{colour}", alpha=0.45, linewidth=1.0)
            if evaluated:
                axes.plot(*zip(*evaluated, strict=True), color=f"C{colour}", marker="o", linewidth=1.6,
                          label=label if number == 0 else None)
    axes.set_xlabel("training wall time (min)")
    axes.set_ylabel("success rate (dots: evaluation, line: training)")
    axes.set_ylim(0, 1.02)
    axes.grid(alpha=0.3)
    axes.legend()
    axes.set_title(title)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(path, dpi=120, bbox_inches="tight")
    plt.close(figure)
    return path
