"""``scipy.stats``, imported on first use.

``from scipy import stats`` takes about 0.5 s (it builds every distribution with its
docstring), longer than the whole Algorithm A analysis of a 200,000-result round. A fresh
process such as ``pt_compare`` would pay it at start-up although only some methods use a
χ² quantile (the weighted mean's χ² test, Algorithm S). ``from analysis.core.lazy import
stats`` gives a stand-in whose first attribute access imports the real module.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any


class LazyModule:
    """A module imported when one of its attributes is first used."""

    def __init__(self, name: str) -> None:
        self._name = name

    def __getattr__(self, attr: str) -> Any:
        return getattr(importlib.import_module(self._name), attr)


if TYPE_CHECKING:
    from scipy import stats
else:
    stats = LazyModule("scipy.stats")

__all__ = ["LazyModule", "stats"]
