"""What git tracks stays small: no run outputs, no large files outside the places meant for them.

Run outputs (TensorBoard event files, checkpoints, per-episode tables) belong in ``runs/`` (ignored by
``.gitignore``); what the docs cite from them is extracted into small files (``make report``), and agents that are
inputs ship in ``agrl/baselines/`` (``python -m agrl.baselines``). The check reads the git index (``git ls-files``),
so it sees what the next commit would hold; outside a git checkout (an installed wheel) it is skipped.
"""

from __future__ import annotations

import fnmatch
import shutil
import subprocess
from collections.abc import Iterable
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

MAX_FILE_BYTES = 1_000_000
MAX_TREE_BYTES = 25_000_000
#: Files allowed over MAX_FILE_BYTES (fnmatch patterns on the path; ``*`` also matches ``/``): the shipped agents
#: and the documentation's figures. They still count towards MAX_TREE_BYTES.
LARGE_FILES_ALLOWED = (
    "agrl/baselines/*.pt",
    "docs/results/figures/*",
    "docs/*.png", "docs/*.svg", "docs/*.jpg", "docs/*.gif",
)


def repository_violations(files: Iterable[tuple[str, int]]) -> list[str]:
    """One line per problem in a list of tracked files (path relative to the repository root, size in bytes):
    a TensorBoard event file, a file over :data:`MAX_FILE_BYTES` outside :data:`LARGE_FILES_ALLOWED`, a tree over
    :data:`MAX_TREE_BYTES`."""
    files = list(files)
    problems = []
    for path, size in files:
        if ".tfevents." in Path(path).name:
            problems.append(f"{path}: a TensorBoard event file is tracked; run outputs stay in runs/ (.gitignore), "
                            "and make report extracts what the docs cite")
        elif size > MAX_FILE_BYTES and not any(fnmatch.fnmatch(path, pattern) for pattern in LARGE_FILES_ALLOWED):
            problems.append(f"{path}: {size} bytes tracked, over {MAX_FILE_BYTES}; allowed that large only: "
                            f"{', '.join(LARGE_FILES_ALLOWED)} (run outputs stay in runs/, agents that are inputs "
                            "ship in agrl/baselines/)")
    total = sum(size for _, size in files)
    if total > MAX_TREE_BYTES:
        largest, size = max(files, key=lambda item: item[1])
        problems.append(f"the tracked tree holds {total} bytes, over {MAX_TREE_BYTES} (the largest file: {largest}, "
                        f"{size} bytes)")
    return problems


def tracked_files() -> list[tuple[str, int]]:
    """(path, size in bytes) of every file in the git index, sizes from the stored blobs."""
    if shutil.which("git") is None:
        pytest.skip("git is not installed")
    listing = subprocess.run(["git", "ls-files", "--stage", "-z"], cwd=ROOT, capture_output=True, timeout=60)
    if listing.returncode != 0:
        pytest.skip(f"{ROOT} is not a git checkout (an installed package): nothing tracked to check")
    entries = [entry.split("\t", 1) for entry in listing.stdout.decode().split("\0") if entry]
    entries = [(fields, path) for fields, path in entries if not fields.startswith("160000")]  # submodules: no blob
    paths = [path for _, path in entries]
    objects = [fields.split()[1] for fields, _ in entries]
    sizes = subprocess.run(["git", "cat-file", "--batch-check=%(objectsize)"], cwd=ROOT, check=True, timeout=120,
                           input="\n".join(objects) + "\n", capture_output=True, text=True).stdout.split()
    assert len(sizes) == len(paths), "git cat-file answered for fewer objects than git ls-files listed"
    return [(path, int(size)) for path, size in zip(paths, sizes, strict=True)]


@pytest.fixture(scope="module")
def files() -> list[tuple[str, int]]:
    return tracked_files()


def test_no_run_outputs_or_large_files_are_tracked(files):
    problems = repository_violations(files)
    assert not problems, problems[0] + (f" (and {len(problems) - 1} more)" if len(problems) > 1 else "")


def test_each_violation_is_one_line_naming_the_file():
    small = MAX_FILE_BYTES // 10
    files = [
        ("agrl/core/dynamics.py", small),
        ("runs/fixed/scratch/run/tensorboard/events.out.tfevents.1764633600.host.1.0", small),
        ("docs/results/data/episodes.csv", MAX_FILE_BYTES + 1),
        ("agrl/baselines/fixed_baseline.pt", MAX_FILE_BYTES + 1),  # a shipped agent: allowed
        ("docs/results/figures/moving.png", MAX_FILE_BYTES + 1),  # a doc figure: allowed
    ]
    problems = repository_violations(files)
    assert problems == [
        "runs/fixed/scratch/run/tensorboard/events.out.tfevents.1764633600.host.1.0: a TensorBoard event file is "
        "tracked; run outputs stay in runs/ (.gitignore), and make report extracts what the docs cite",
        f"docs/results/data/episodes.csv: {MAX_FILE_BYTES + 1} bytes tracked, over {MAX_FILE_BYTES}; allowed that "
        f"large only: {', '.join(LARGE_FILES_ALLOWED)} (run outputs stay in runs/, agents that are inputs ship in "
        "agrl/baselines/)",
    ]
    assert all("\n" not in problem for problem in problems)


def test_a_tree_over_the_limit_names_its_largest_file():
    count = MAX_TREE_BYTES // MAX_FILE_BYTES + 1
    files = [(f"docs/results/figures/figure_{index}.png", MAX_FILE_BYTES) for index in range(count)]
    files.append(("docs/results/figures/largest.png", MAX_FILE_BYTES + 5))
    total = count * MAX_FILE_BYTES + MAX_FILE_BYTES + 5
    assert repository_violations(files) == [
        f"the tracked tree holds {total} bytes, over {MAX_TREE_BYTES} (the largest file: "
        f"docs/results/figures/largest.png, {MAX_FILE_BYTES + 5} bytes)"
    ]
    assert repository_violations(files[:3]) == []


#: The most lines a module of agrl may have: a longer one does several jobs (split it by job).
MAX_MODULE_LINES = 450


def oversized_modules(package: Path) -> list[str]:
    """``<path>: <n> lines (at most ...)`` for each module of ``package`` over :data:`MAX_MODULE_LINES`."""
    return [f"{path.relative_to(package.parent)}: {count} lines (at most {MAX_MODULE_LINES})"
            for path in sorted(package.rglob("*.py"))
            if (count := len(path.read_text().splitlines())) > MAX_MODULE_LINES]


def test_no_module_of_agrl_is_over_the_line_limit():
    assert oversized_modules(ROOT / "agrl") == []


def test_an_oversized_module_is_named(tmp_path):
    package = tmp_path / "agrl"
    package.mkdir()
    (package / "small.py").write_text("x = 1\n" * MAX_MODULE_LINES)
    (package / "large.py").write_text("x = 1\n" * (MAX_MODULE_LINES + 1))
    assert oversized_modules(package) == [f"agrl/large.py: {MAX_MODULE_LINES + 1} lines (at most {MAX_MODULE_LINES})"]
