"""Data folders to runs: the rows of a data folder (of a path below one, or of a folder of runs, extracted in
memory), and the runs among them, each with its curve and its independent evaluations."""

from __future__ import annotations

import fnmatch
from collections import defaultdict
from pathlib import Path

from agrl.report.columns import DATA_FILES, read_csv
from agrl.report.extract import extract


def data_folder_above(path: str | Path) -> Path | None:
    """The data folder (with ``runs.csv``) that ``path`` is or lies below (the path need not exist), or None."""
    path = Path(path).absolute()
    return next((folder for folder in (path, *path.parents) if (folder / "runs.csv").is_file()), None)


def load_data(folder: str | Path) -> dict[str, list]:
    """A data folder's rows (:func:`extract`'s form). A path below a data folder (``data/switch_finetune/
    position_2026-12-03``) is that folder's runs and evaluations below it, named from there on, as from the same
    path among the runs; a folder of runs (no ``runs.csv`` in or above it) is extracted in memory."""
    above = data_folder_above(folder)
    if above is None:
        return extract(folder)
    data: dict[str, list] = {"files": []}
    for name, columns in DATA_FILES.items():
        data[name] = read_csv(above / name, columns) if (above / name).is_file() else []
    prefix = Path(folder).absolute().relative_to(above).as_posix()
    if prefix == ".":
        return data

    def below(name: str | None) -> str | None:
        """``name`` relative to the prefix, or None if it is not below it."""
        if name is None or not (name == prefix or name.startswith(prefix + "/")):
            return None
        return name[len(prefix) + 1:] or "."

    for name in ("runs.csv", "curves.csv"):
        data[name] = [{**row, "run": below(row["run"])} for row in data[name] if below(row["run"]) is not None]
    data["evaluations.csv"] = [{**row, "run": below(row["run"]), "evaluation": below(row["evaluation"])}
                               for row in data["evaluations.csv"] if below(row["evaluation"]) is not None]
    return data


def assemble_runs(data: dict[str, list], patterns: tuple[str, ...] = ()) -> list[dict]:
    """The runs of ``data`` (those whose path matches one of ``patterns``, if any), each its ``runs.csv`` row with
    ``curve`` (its periodic evaluations, oldest first) and ``evaluations`` (its independent ones, by folder)."""
    curves: dict[str, list] = defaultdict(list)
    for row in data["curves.csv"]:
        curves[row["run"]].append(row)
    independent: dict[str, list] = defaultdict(list)
    for row in data["evaluations.csv"]:
        if not row["final"] and row["run"]:
            independent[row["run"]].append(row)
    return [{**row, "curve": curves[row["run"]], "evaluations": independent[row["run"]]}
            for row in data["runs.csv"] if not patterns or any(fnmatch.fnmatchcase(row["run"], pattern)
                                                                for pattern in patterns)]


def finished(runs: list[dict]) -> list[dict]:
    """The runs with a final evaluation (the tables' input)."""
    return [run for run in runs if run["success"] is not None]
