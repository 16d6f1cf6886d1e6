"""pyproject.toml ships every config group of conf/ (setuptools ships data only from listed packages)."""

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
