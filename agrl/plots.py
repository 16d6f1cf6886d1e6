"""Figures: 3-D trajectories (the paper's Figures 6, 8, 10) and success against wall time (Figures 5, 7, 9)."""

from __future__ import annotations

import csv
from collections.abc import Mapping, Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files only; no display needed
import matplotlib.pyplot as plt  # noqa: E402

from agrl.core.termination import Airspace, Outcome  # noqa: E402

OUTCOME_COLOURS = {
    Outcome.SUCCESS: "tab:green",
    Outcome.OUT_OF_AIRSPACE: "tab:red",
    Outcome.BUDGET_EXHAUSTED: "tab:orange",
    Outcome.RUNNING: "tab:gray",
}


def plot_trajectories(records, path: str | Path, airspace: Airspace | None = None, count: int = 10,
                      title: str = "") -> Path:
    """Aircraft paths (coloured by outcome) and destination paths (black) of the first ``count`` episodes, in km."""
    if records.trajectory_aircraft is None:
        raise ValueError("records carry no trajectories: run_episodes(..., record_trajectories=True)")
    airspace = airspace or Airspace()
    figure = plt.figure(figsize=(8, 6.5))
    axes = figure.add_subplot(projection="3d")
    count = min(count, records.outcome.numel())
    for index in range(count):
        length = int(records.decisions[index]) + 1
        aircraft = records.trajectory_aircraft[index, :length, :3] / 1000.0
        destination = records.trajectory_destination[index, :length, :3] / 1000.0
        colour = OUTCOME_COLOURS[Outcome(int(records.outcome[index]))]
        axes.plot(aircraft[:, 0], aircraft[:, 1], aircraft[:, 2], color=colour, linewidth=1.2)
        axes.scatter(*aircraft[0].tolist(), color=colour, marker="o", s=12)
        axes.plot(destination[:, 0], destination[:, 1], destination[:, 2], color="black", linewidth=1.0)
        axes.scatter(*destination[-1].tolist(), color="black", marker="x", s=20)
    axes.set_xlim(airspace.x_min / 1000, airspace.x_max / 1000)
    axes.set_ylim(airspace.y_min / 1000, airspace.y_max / 1000)
    axes.set_zlim(airspace.z_min / 1000, airspace.z_max / 1000)
    axes.set_xlabel("x (km)")
    axes.set_ylabel("y (km)")
    axes.set_zlabel("z (km)")
    handles = [plt.Line2D([], [], color=c, label=o.name.lower().replace("_", " "))
               for o, c in OUTCOME_COLOURS.items() if o is not Outcome.RUNNING]
    handles.append(plt.Line2D([], [], color="black", label="destination"))
    axes.legend(handles=handles, loc="upper left", fontsize=8)
    axes.set_title(title or f"{count} evaluation episodes")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(path, dpi=120, bbox_inches="tight")
    plt.close(figure)
    return path


def read_metrics(path: str | Path) -> list[dict[str, float]]:
    """Rows of a run's ``metrics.csv`` (empty cells become None)."""
    rows = []
    with Path(path).open() as file:
        for row in csv.DictReader(file):
            rows.append({key: (float(value) if value not in ("", None) else None) for key, value in row.items()})
    return rows


def plot_success_against_time(curves: Mapping[str, Sequence[Path]], path: str | Path, title: str = "",
                              key: str = "eval/success_rate") -> Path:
    """Success against training wall time, one colour per label (the paper's Figures 5, 7 and 9).

    Large dots: ``key`` (by default the periodic evaluation over the full start box); thin line: the training
    success of each iteration (with the curriculum, scratch runs train on easier starts first).
    """
    figure, axes = plt.subplots(figsize=(7, 4.5))
    for colour, (label, files) in enumerate(curves.items()):
        for number, file in enumerate(files):
            rows = read_metrics(file)
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
