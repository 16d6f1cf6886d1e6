"""A ``torch.compile``d function that falls back to its eager original if compilation fails."""

from __future__ import annotations

import warnings
from collections.abc import Callable
from typing import Any


class EagerFallback:
    """Calls ``compiled``; if that raises (no C++ compiler, an unsupported platform), warns once, naming
    ``what``, and calls ``eager`` from then on. An error of the eager function itself is raised as it is."""

    def __init__(self, compiled: Callable, eager: Callable, what: str):
        self.eager = eager
        self.what = what
        self._call = compiled

    @property
    def compiled(self) -> bool:
        """False once compilation has failed (and always if ``compiled`` is ``eager``)."""
        return self._call is not self.eager

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        try:
            return self._call(*args, **kwargs)
        except Exception as error:  # noqa: BLE001 - any compiler failure falls back to eager
            if self._call is self.eager:
                raise
            warnings.warn(f"torch.compile of {self.what} failed ({type(error).__name__}: {error}); running eagerly",
                          RuntimeWarning, stacklevel=3)
            self._call = self.eager
            return self.eager(*args, **kwargs)
