"""Read side of the raw records: who sees which records, the stored
files read back into records, and the record-with-fit figure.  Each owns its joins."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, cast

from django.db.models import QuerySet

from analysis.core.signals.records import Record
from common import quantities
from common.errors import NotVisible, ValidationFailed
from common.points import PointKey, point_label
from labs.models import Participant, RawFile, RawRecomputation, RawRecord
from labs.raw import fit_figure_svg, read_record
from proficiency.models import MeasurementPoint

# --- reads -------------------------------------------------------------------------------


def raw_records_of(participant: Participant) -> QuerySet[RawRecord]:
    return _with_joins(RawRecord.objects.filter(participant=participant))


def raw_records_of_comparison(comparison_id: int) -> QuerySet[RawRecord]:
    return _with_joins(RawRecord.objects.filter(participant__comparison_id=comparison_id))


def _with_joins(qs: QuerySet[RawRecord]) -> QuerySet[RawRecord]:
    return qs.select_related(
        "participant", "submission", "measurement_point__device", "data_file",
        "reference_file", "recomputation",
    ).order_by("participant__code", "-created_at", "-pk")  # fmt: skip


def raw_record_get(records: QuerySet[RawRecord], pk: int) -> RawRecord:
    record = records.filter(pk=pk).first()
    if record is None:
        raise NotVisible(f"No raw record {pk} is visible to you.")
    return record


def raw_record_read(record: RawRecord) -> tuple[Record, Record | None]:
    """The stored files read back into records (the same readers as at upload)."""
    mems = read_record(_bytes(record.data_file), record.data_name, record.metadata)
    reference = None
    if record.reference_file is not None:
        reference = read_record(
            _bytes(record.reference_file), record.reference_name, record.reference_metadata
        )
    return mems, reference


def _bytes(raw: RawFile) -> bytes:
    with raw.file.open("rb") as fh:
        return fh.read()


def raw_record_figure(record: RawRecord) -> str | None:
    """SVG of a stretch of the point's channel with the fitted sine at the rate found (the
    gyroscope's ``g<axis>`` for an angular-rate point); None until the recomputation has
    succeeded."""
    row = getattr(record, "recomputation", None)
    if row is None or row.status != RawRecomputation.Status.SUCCEEDED or row.fs_hz is None:
        return None
    point = record.measurement_point
    name = f"G{point.axis}" if point.quantity == quantities.ANGULAR_RATE else point.axis
    axis = next((a for a in row.axes if a["axis"] == name and a["sensitivity"]), None)
    f = axis["analysis_frequency_hz"] if axis else point.frequency_hz
    mems, _ = raw_record_read(record)
    return fit_figure_svg(mems, name.lower(), f, row.fs_hz)


def raw_point_choices(participant: Participant) -> QuerySet[MeasurementPoint]:
    """Points where the participant's current submission has a result (linear and
    curvilinear benches: the ones a raw record can be recomputed on)."""
    submission = participant.submissions.order_by("-version").first()
    return (
        MeasurementPoint.objects.filter(
            results__submission=submission, bench__in=("linear", "curvilinear")
        )
        .select_related("device")
        .order_by(*cast(list[str], MeasurementPoint._meta.ordering))
    )


# --- the point a raw record names -------------------------------------------------------


def raw_point_find(participant: Participant, fields: Mapping[str, Any]) -> MeasurementPoint:
    """The comparison's point named like a results-table row (docs/interfaces.md §1 columns,
    ``quantity`` blank or absent meaning ``magnitude``).  A point that exists only as other
    kinds is refused, naming them: the kind decides which figure is compared, so it is
    never guessed."""
    quantity = _quantity(fields)
    same = MeasurementPoint.objects.filter(
        comparison=participant.comparison,
        device__name=fields["device"],
        axis=str(fields["axis"]).upper(),
        frequency_hz=fields["frequency_hz"],
        bench=fields["bench"],
        direction=fields.get("direction") or "vertical",
        amplitude_m_s2=fields.get("amplitude_m_s2"),
    )
    found = same.filter(quantity=quantity).first()
    if found is None:
        others = sorted(set(same.values_list("quantity", flat=True)))
        hint = (
            f"it has that point as {', '.join(others)} only: name the quantity "
            f"(quantity={others[0]})"
            if others
            else "see the comparison's measurement points (the results template lists them)"
        )
        raise ValidationFailed(
            f"{participant.comparison.code} has no measurement point {_named(fields)} "
            f"({quantities.kind(quantity).label}); {hint}.",
            errors=[{"field": "quantity" if others else "device",
                     "message": "no such measurement point"}],
        )  # fmt: skip
    return found


def _named(fields: Mapping[str, Any]) -> str:
    """The point the fields name, as people write it (``IMU 1, X, 160 Hz, linear vertical``)."""
    try:
        f = float(fields["frequency_hz"])
    except (TypeError, ValueError):
        return ", ".join(f"{k} {fields.get(k)}" for k in PointKey._fields if fields.get(k))
    key = PointKey(str(fields["device"]), str(fields["axis"]).upper(), f, str(fields["bench"]),
                   fields.get("direction") or "vertical", fields.get("amplitude_m_s2"))  # fmt: skip
    return point_label(key)


def _quantity(fields: Mapping[str, Any]) -> str:
    """The named kind (``common.quantities.parse``); 400 on the field otherwise."""
    try:
        return quantities.parse(fields.get("quantity"))
    except ValueError as exc:
        message = f"quantity {exc}"
        error = {"field": "quantity", "message": message}
        raise ValidationFailed(message, errors=[error]) from None
