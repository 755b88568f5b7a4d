"""Read-side queries of the comparison domain; each owns its joins."""

from __future__ import annotations

from typing import cast

from proficiency.models import MeasurementPoint

#: Rows related to a measurement point in the points' own order (device, axis, frequency, ...).
POINT_ORDER = [f"measurement_point__{f}" for f in cast(list[str], MeasurementPoint._meta.ordering)]
