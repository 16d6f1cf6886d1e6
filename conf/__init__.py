"""Hydra configs of agrl. Installed as the package ``agrl.conf`` (see pyproject.toml), so that
``python -m agrl.train`` finds them from a wheel as well as from this checkout (``pkg://agrl.conf``)."""
