"""Sensitivity of one raw record on its bench (docs/interfaces.md §5, ``pt_sensitivity``)."""

from __future__ import annotations

from analysis.core.signals.curvilinear import curvilinear_sensitivity
from analysis.core.signals.linear import linear_sensitivity
from analysis.core.signals.measure import Method
from analysis.core.signals.records import Record, SignalInputError
from analysis.core.signals.results import SensitivityResult

METHODS = ("sine-fit", "paper")


def record_sensitivity(
    mems: Record, reference: Record | None = None, method: Method = "sine-fit"
) -> SensitivityResult:
    """Dispatch on ``bench`` of the record's metadata (docs/domain.md §8.1 / §8.2)."""
    if method not in METHODS:
        raise SignalInputError(f"method must be one of {', '.join(METHODS)}, got {method!r}")
    bench = mems.meta.get("bench")
    if bench == "linear":
        return linear_sensitivity(mems, reference, method)
    if bench == "curvilinear":
        return curvilinear_sensitivity(mems, reference, method)
    raise SignalInputError(f"{mems.name}: bench must be linear or curvilinear (got {bench!r})")
