"""The one-line errors of the configuration: :class:`ConfigError` and the range checks every schema uses."""

from __future__ import annotations

import re
from typing import Any


class ConfigError(ValueError):
    """A configuration value is out of range; the message is one line."""


def one_line(value: Any, limit: int = 200) -> str:
    """``repr(value)`` for a one-line error message: on one line (a numpy array or a tensor of several rows
    prints them on lines of their own) and cut to ``limit`` characters."""
    text = " ".join(repr(value).split())
    return text if len(text) <= limit else f"{text[:limit]}..."


def require(condition: bool, key: str, value: Any, allowed: str) -> None:
    """Raise :class:`ConfigError` ``<key>=<value> is not allowed: <allowed>`` unless ``condition``."""
    if not condition:
        raise ConfigError(f"{key}={value!r} is not allowed: {allowed}")


def require_device(key: str, device: str) -> None:
    """``cpu``, ``cuda`` or ``cuda:N``, and only a CUDA device this machine has."""
    require(device == "cpu" or re.fullmatch(r"cuda(:\d+)?", device) is not None, key, device,
             "cpu, cuda or cuda:N")
    if device.startswith("cuda"):
        import torch

        count = torch.cuda.device_count() if torch.cuda.is_available() else 0
        index = int(device.partition(":")[2] or 0)
        available = ", ".join(["cpu"] + [f"cuda:{n}" for n in range(count)])
        require(index < count, key, device, f"this machine has {available} (torch {torch.__version__})")


def require_range_pair(key: str, pair: list[float], low: float, high: float, unit: str) -> None:
    """``pair`` is ``[low, high]`` with low <= high, within ``[low, high]``."""
    require(len(pair) == 2 and pair[0] <= pair[1], key, pair, f"a [low, high] pair with low <= high ({unit})")
    require(low <= pair[0] and pair[1] <= high, key, pair, f"within [{low}, {high}] {unit}")
