"""A plan's figure: the top view and the altitude against time, each instruction marked where it is given."""

from __future__ import annotations

from pathlib import Path

from agrl.core.parameters import GuidanceParameters
from agrl.core.termination import Outcome
from agrl.plan import Plan


def _extent(values: list[float], low: float, high: float, margin: float = 1.0) -> tuple[float, float]:
    """The range of ``values`` (km) with ``margin`` km either side, inside [low, high]."""
    return max(low, min(values) - margin), min(high, max(values) + margin)


def plan_figure(result: Plan, params: GuidanceParameters, title: str = ""):
    """A top view and the altitude against time, each instruction marked where it is given and numbered, with the
    numbered instructions listed beside them."""
    from agrl.plots import OUTCOME_COLOURS, plt

    colour = OUTCOME_COLOURS[Outcome[result.outcome.upper()]]
    space = params.simulation.airspace
    aircraft, destination = result.trajectory.aircraft, result.trajectory.destination
    xs = [row[0] / 1000 for row in aircraft + destination]
    ys = [row[1] / 1000 for row in aircraft + destination]
    figure, (top, side) = plt.subplots(1, 2, figsize=(12, 5.5), width_ratios=(1.2, 1.0))
    top.plot([row[0] / 1000 for row in aircraft], [row[1] / 1000 for row in aircraft], color=colour, label="aircraft")
    top.plot([row[0] / 1000 for row in destination], [row[1] / 1000 for row in destination], color="black",
             label="destination")
    top.scatter(destination[-1][0] / 1000, destination[-1][1] / 1000, color="black", marker="x", s=30)
    side.plot(result.trajectory.time_s, [row[2] / 1000 for row in aircraft], color=colour)
    side.plot(result.trajectory.time_s, [row[2] / 1000 for row in destination], color="black")
    listed = []
    for number, instruction in enumerate(result.instructions, 1):
        x, y, z = (value / 1000 for value in instruction.position)
        for axes, point in ((top, (x, y)), (side, (instruction.time_s, z))):
            axes.scatter(*point, color="tab:blue", s=18, zorder=3)
            axes.annotate(str(number), point, textcoords="offset points", xytext=(3, 3), fontsize=8)
        listed.append(f"{number}  t={instruction.time_s:.0f} s  {instruction.text}")
    side.text(1.02, 1.0, "\n".join(listed), transform=side.transAxes, va="top", fontsize=8, family="monospace")
    top.set_xlim(*_extent(xs, space.x_min / 1000, space.x_max / 1000))
    top.set_ylim(*_extent(ys, space.y_min / 1000, space.y_max / 1000))
    top.set_aspect("equal")
    top.set(xlabel="x (km)", ylabel="y (km)", title="top view")
    top.legend(loc="best", fontsize=8)
    side.set_ylim(space.z_min / 1000, space.z_max / 1000)
    side.set(xlabel="time (s)", ylabel="z (km)", title="altitude")
    figure.suptitle(f"{title}  {result.lines()[-1]}".strip(), fontsize=10)
    return figure


def draw_plan(result: Plan, params: GuidanceParameters, path: str | Path, title: str = "") -> Path:
    """:func:`plan_figure` written to ``path`` (PNG)."""
    from agrl.plots import plt

    figure = plan_figure(result, params, title)
    figure.savefig(path, dpi=120, bbox_inches="tight")
    plt.close(figure)
    return Path(path)
