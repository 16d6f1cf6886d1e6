"""pyproject.toml ships every config group of conf/ and every shipped agent (setuptools ships data only from listed
packages and package-data patterns)."""

import fnmatch
import tomllib
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def test_every_config_group_is_a_listed_package():
    setuptools = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]
    assert setuptools["package-dir"]["agrl.conf"] == "conf"
    groups = {f"agrl.conf.{path.parent.name}" for path in (REPO / "conf").glob("*/*.yaml")}
    assert groups, "conf/ has no config groups"
    listed = set(setuptools["packages"])
    assert groups <= listed, f"config groups missing from [tool.setuptools] packages: {sorted(groups - listed)}"
    assert "*.yaml" in setuptools["package-data"]["*"]


def test_every_shipped_agent_and_its_evaluation_record_is_package_data():
    from agrl.baselines import SHIPPED_AGENTS

    patterns = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]["package-data"]["agrl"]
    for agent in SHIPPED_AGENTS.values():
        for path in (agent.file, agent.evaluations_file):
            relative = path.relative_to(REPO / "agrl").as_posix()
            assert any(fnmatch.fnmatch(relative, pattern) for pattern in patterns), \
                f"agrl/{relative} ({agent.name}) matches none of pyproject's agrl package-data: {patterns}"


def test_every_python_package_of_agrl_is_listed():
    # A package left out of the list is silently missing from the wheel (an ImportError only once installed).
    packages = {".".join(path.parent.relative_to(REPO).parts) for path in (REPO / "agrl").rglob("__init__.py")}
    listed = set(tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    assert packages <= listed, f"packages missing from [tool.setuptools] packages: {sorted(packages - listed)}"
