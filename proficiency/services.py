"""Services of the comparison domain: the status state machine, templates, the point grid."""

from __future__ import annotations

import datetime as dt
import itertools
from collections.abc import Iterable, Sequence
from typing import TYPE_CHECKING, Any, TypedDict, Unpack

from django.db import transaction
from django.db.models import Q
from django.utils import timezone

from common.errors import InvalidTransition, StateConflict, ValidationFailed
from common.quantities import DEFAULT as DEFAULT_QUANTITY
from common.quantities import NAMES as KIND_NAMES
from proficiency import protocols
from proficiency.models import (
    DEFAULT_UNIT,
    FLOAT_MAX,
    Comparison,
    ComparisonStatus,
    Device,
    Distribution,
    MeasurementPoint,
)

if TYPE_CHECKING:
    from django.contrib.auth.models import User

S = ComparisonStatus

# The one place where the comparison life cycle is defined.  A closed comparison
# may be reopened (e.g. a deadline extension); an analysed one may go back to
# closed so that corrected submissions can be reviewed and re-analysed.
# Published is final: a correction after publication is a reissued report.
COMPARISON_TRANSITIONS: dict[str, frozenset[str]] = {
    S.DRAFT: frozenset({S.OPEN}),
    S.OPEN: frozenset({S.CLOSED}),
    S.CLOSED: frozenset({S.OPEN, S.ANALYSED}),
    S.ANALYSED: frozenset({S.CLOSED, S.PUBLISHED}),
    S.PUBLISHED: frozenset(),
}


def comparison_allowed_transitions(comparison: Comparison) -> list[str]:
    return sorted(COMPARISON_TRANSITIONS[comparison.status])


def comparison_transition_check(*, comparison: Comparison, to: str) -> None:
    """InvalidTransition unless the life cycle allows ``comparison`` (as given: the caller
    reads it under its lock) to go to ``to``; a move made later (publication, in the
    background) is refused up front with the message the move itself would give."""
    if to not in S.values:
        raise InvalidTransition(f"Unknown comparison status {to!r}; known: {', '.join(S.values)}.")
    allowed = COMPARISON_TRANSITIONS[comparison.status]
    if to not in allowed:
        nexts = ", ".join(sorted(allowed)) or "none (published is final)"
        raise InvalidTransition(
            f"Comparison {comparison.code} cannot go from {comparison.status} to {to}; "
            f"allowed next status: {nexts}."
        )


# --- the call for participation (docs/lifecycles.md §7) ------------------------------------

#: the states in which a round takes applications: before its results are collected
ENROLMENT_STATES = (S.DRAFT, S.OPEN)


def enrolment_check(comparison: Comparison, *, now: dt.datetime | None = None) -> None:
    """StateConflict (409) saying why ``comparison`` takes no application now: the call is
    open while ``enrolment_open`` is set, the round is draft or open, and neither
    ``enrolment_closes`` nor the submission deadline has passed. The same rule as
    :func:`enrolment_open_filter`."""
    now = now or timezone.now()
    code = comparison.code
    if not comparison.enrolment_open:
        raise StateConflict(f"{code} takes no applications: its call for participation is closed.")
    if comparison.status not in ENROLMENT_STATES:
        raise StateConflict(
            f"{code} is {comparison.get_status_display().lower()}: applications are taken only "
            "while a round is in preparation or open."
        )
    closes = comparison.enrolment_closes
    if closes is not None and now >= closes:
        raise StateConflict(f"The enrolment of {code} closed on {closes:%Y-%m-%d %H:%M} UTC.")
    deadline = comparison.submission_deadline
    if deadline is not None and now >= deadline:
        raise StateConflict(
            f"The submission deadline of {code} passed on {deadline:%Y-%m-%d %H:%M} UTC: "
            "it takes no more applications."
        )


def enrolment_open_filter(*, now: dt.datetime | None = None) -> Q:
    """The comparisons whose call is open now (:func:`enrolment_check`'s rule as a filter)."""
    now = now or timezone.now()
    return (
        Q(enrolment_open=True, status__in=ENROLMENT_STATES)
        & (Q(enrolment_closes__isnull=True) | Q(enrolment_closes__gt=now))
        & (Q(submission_deadline__isnull=True) | Q(submission_deadline__gt=now))
    )


@transaction.atomic
def comparison_transition(*, comparison: Comparison, to: str) -> Comparison:
    """Move a comparison to status ``to`` if the life cycle allows it, under a row lock."""
    locked = Comparison.objects.select_for_update().get(pk=comparison.pk)
    comparison_transition_check(comparison=locked, to=to)
    if to == S.OPEN and not locked.measurement_points.exists():
        raise InvalidTransition(
            f"Comparison {locked.code} has no measurement points; add them before opening it."
        )
    locked.status = to
    locked.save(update_fields=["status", "updated_at"])
    comparison.status = to
    return locked


#: A point by its device's id, as the unique constraint sees it (no query for the device names).
_IdKey = tuple[int, str, float, str, str, float | None, str]


def _point_key(p: MeasurementPoint) -> _IdKey:
    return (p.device_id, p.axis, p.frequency_hz, p.bench, p.direction, p.amplitude_m_s2,
            p.quantity)  # fmt: skip


@transaction.atomic
def measurement_points_generate(
    *,
    comparison: Comparison,
    devices: Sequence[Device],
    axes: Iterable[str],
    frequencies_hz: Iterable[float],
    benches: Iterable[str],
    directions: Iterable[str] | None = None,
    amplitudes: dict[tuple[float, str], float] | None = None,
    quantities: Iterable[str] = (DEFAULT_QUANTITY,),
) -> list[MeasurementPoint]:
    """Create the grid devices × axes × frequencies × benches × directions × quantity kinds
    (``common.quantities``; default the magnitude only); idempotent.

    ``directions`` defaults to each bench's own (vertical on the linear bench,
    tangential and radial on the curvilinear one); a (bench, direction) pair that
    the bench cannot produce is refused.  ``amplitudes`` maps (frequency,
    direction) to the expected excitation amplitude.  Points that already exist
    are kept; the new ones are created in one bulk insert.  Returns the new points.
    """
    axes, freqs, benches = list(axes), [float(f) for f in frequencies_hz], list(benches)
    _check_grid(comparison, devices, axes, freqs, benches)
    kinds = _kinds(quantities)
    existing = {_point_key(p) for p in comparison.measurement_points.all()}
    new: list[MeasurementPoint] = []
    for bench in benches:
        dirs = list(directions) if directions is not None else _bench_directions(bench)
        grid = itertools.product(devices, axes, freqs, dirs, kinds)
        for device, axis, f, direction, quantity in grid:
            _check_direction(bench, direction)
            amp = (amplitudes or {}).get((f, direction))
            point = MeasurementPoint(
                comparison=comparison,
                device=device,
                axis=axis,
                frequency_hz=f,
                bench=bench,
                direction=direction,
                amplitude_m_s2=amp,
                quantity=quantity,
            )
            if _point_key(point) not in existing:
                existing.add(_point_key(point))
                new.append(point)
    return MeasurementPoint.objects.bulk_create(new)


def _kinds(quantities: Iterable[str]) -> list[str]:
    """The kinds asked for, each known to the registry, in the order given."""
    kinds = list(dict.fromkeys(quantities))
    bad = [q for q in kinds if q not in KIND_NAMES]
    if bad or not kinds:
        raise ValidationFailed(
            f"Cannot generate the measurement grid: unknown quantity {', '.join(map(repr, bad))}"
            f" (use {', '.join(KIND_NAMES)})." if bad else
            "Cannot generate the measurement grid: at least one quantity is needed."
        )  # fmt: skip
    return kinds


def _bench_directions(bench: str) -> list[str]:
    return list(protocols.DIRECTIONS_BY_BENCH.get(bench, ("vertical",)))


def _check_direction(bench: str, direction: str) -> None:
    allowed = protocols.DIRECTIONS_BY_BENCH.get(bench)
    if allowed is not None and direction not in allowed:
        raise ValidationFailed(
            f"Direction {direction!r} is not possible on the {bench} bench "
            f"(allowed: {', '.join(allowed)})."
        )


def _check_grid(
    comparison: Comparison,
    devices: Sequence[Device],
    axes: list[str],
    freqs: list[float],
    benches: list[str],
) -> None:
    errors = []
    if not devices:
        errors.append("at least one device is needed")
    if any(d.comparison_id != comparison.pk for d in devices):
        errors.append("every device must belong to this comparison")
    if bad := [a for a in axes if a not in ("X", "Y", "Z")]:
        errors.append(f"unknown axes {bad} (use X, Y, Z)")
    if not axes:
        errors.append("at least one axis is needed")
    if not freqs or any(not (f > 0 and f < float("inf")) for f in freqs):
        errors.append("frequencies must be finite and > 0")
    if not benches:
        errors.append("at least one bench is needed")
    if errors:
        raise ValidationFailed("Cannot generate the measurement grid: " + "; ".join(errors) + ".")


@transaction.atomic
def comparison_apply_template(
    *,
    comparison: Comparison,
    template_key: str,
    devices: Sequence[Device],
    quantities: Iterable[str] = (DEFAULT_QUANTITY,),
) -> list[MeasurementPoint]:
    """Generate the measurement points of a seed protocol (docs/domain.md §8) for ``devices``:
    of each kind in ``quantities`` that a bench of the template offers (the magnitude by
    default; the benches' ``quantities`` say what each offers)."""
    try:
        template = protocols.TEMPLATES[template_key]
    except KeyError:
        known = ", ".join(protocols.TEMPLATES)
        raise ValidationFailed(
            f"Unknown protocol template {template_key!r}; known: {known}."
        ) from None
    wanted = _kinds(quantities)
    offered = {q for plan in template.benches for q in plan.quantities}
    if missing := [q for q in wanted if q not in offered]:
        raise ValidationFailed(
            f"The template {template_key!r} offers no {', '.join(missing)} points; it offers "
            f"{', '.join(q for q in KIND_NAMES if q in offered)}."
        )
    created: list[MeasurementPoint] = []
    for plan in template.benches:
        kinds = [q for q in wanted if q in plan.quantities]
        if not kinds:
            continue
        created += measurement_points_generate(
            comparison=comparison,
            devices=devices,
            axes=template.axes,
            frequencies_hz=plan.frequencies_hz,
            benches=[plan.bench],
            directions=plan.directions,
            amplitudes=plan.amplitudes,
            quantities=kinds,
        )
    if comparison.protocol != template_key:
        comparison.protocol = template_key
        comparison.save(update_fields=["protocol", "updated_at"])
    return created


@transaction.atomic
def comparison_create(
    *, comparison: Comparison, template_key: str | None, user: User
) -> Comparison:
    """Store a new (draft) comparison from validated fields; its creator coordinates it."""
    comparison.protocol = template_key or protocols.CUSTOM
    comparison.status = S.DRAFT
    comparison.save()
    comparison.coordinators.add(user)
    return comparison


# --- devices --------------------------------------------------------------------------------


class DeviceFields(TypedDict, total=False):
    """A device's fields other than its name (docs/architecture.md §2: checked here only)."""

    model: str
    serial: str
    unit: str
    nominal_sensitivity: float | None
    tolerance: float | None
    tolerance_relative: bool
    tolerance_distribution: str


#: A device's editable fields, in the order every form, serializer and table shows them.
DEVICE_FIELDS = ["name", *DeviceFields.__annotations__]

DEVICE_NAME_MAX = Device._meta.get_field("name").max_length or 80
_TEXT_MAX = {"model": 80, "serial": 80, "unit": 20}


@transaction.atomic
def device_create(*, comparison: Comparison, name: str, **fields: Unpack[DeviceFields]) -> Device:
    """Add a device to ``comparison``: the name stripped, required, at most 80 characters
    and unique within the comparison; the numbers finite and > 0 when given."""
    defaults: DeviceFields = {
        "unit": DEFAULT_UNIT,
        "tolerance_relative": True,
        "tolerance_distribution": Distribution.RECTANGULAR,
    }
    device = Device(comparison=comparison, **(defaults | fields))
    device.name = _device_name(comparison, name, exclude_pk=None)
    _check_device_fields(device)
    device.save()
    return device


@transaction.atomic
def device_update(
    *, device: Device, name: str | None = None, **fields: Unpack[DeviceFields]
) -> Device:
    """Change a device's name and/or fields under the rules of :func:`device_create`."""
    locked = Device.objects.select_for_update().select_related("comparison").get(pk=device.pk)
    if name is not None:
        locked.name = _device_name(locked.comparison, name, exclude_pk=locked.pk)
    for field, value in fields.items():
        setattr(locked, field, value)
    _check_device_fields(locked)
    locked.save()
    return locked


def _refuse(field: str, message: str) -> ValidationFailed:
    return ValidationFailed(message, errors=[{"field": field, "message": message}])


def _device_name(comparison: Comparison, name: str, *, exclude_pk: int | None) -> str:
    name = name.strip()
    if not name:
        raise _refuse("name", f"A device of {comparison.code} needs a name.")
    if len(name) > DEVICE_NAME_MAX:
        raise _refuse(
            "name",
            f"The device name is {len(name)} characters long; at most {DEVICE_NAME_MAX}.",
        )
    taken = Device.objects.filter(comparison=comparison, name=name)
    if (taken.exclude(pk=exclude_pk) if exclude_pk else taken).exists():
        raise _refuse("name", f"{comparison.code} already has a device named {name!r}.")
    return name


def _check_device_fields(device: Device) -> None:
    errors: list[dict[str, Any]] = []
    for field in ("nominal_sensitivity", "tolerance"):
        value = getattr(device, field)
        if value is not None and not 0 < value <= FLOAT_MAX:
            errors.append({"field": field, "message": f"must be a finite number > 0, got {value}"})
    for field, limit in _TEXT_MAX.items():
        if len(getattr(device, field)) > limit:
            errors.append({"field": field, "message": f"at most {limit} characters"})
    if not device.unit.strip():
        errors.append({"field": "unit", "message": "a device needs a unit"})
    if device.tolerance_distribution not in Distribution.values:
        known = ", ".join(Distribution.values)
        errors.append({"field": "tolerance_distribution", "message": f"one of {known}"})
    if errors:
        where = "; ".join(f"{e['field']}: {e['message']}" for e in errors)
        raise ValidationFailed(f"Device {device.name!r} not stored: {where}.", errors=errors)
