"""Demo data: what the demo's laboratories measured (docs/domain.md §8).

The LSM6DSR devices; the results of the two bench laboratories, which aggregate with the
rule of docs/domain.md §3 exactly to Table 1 of the reference data, and the synthetic
laboratories' plausible scatter; a participant's accepted submission of its results; and
the raw records (docs/interfaces.md §2) behind one laboratory's results.  The rounds of
coordination/demo.py, coordination/demo_earlier.py and coordination/demo_kits.py are made
of these.
"""

from __future__ import annotations

import csv
import datetime as dt
import math
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from django.conf import settings

from analysis.core.signals import synthetic
from common.quantities import point_unit
from labs.models import Participant, Result, Submission
from labs.raw_services import Upload, raw_record_upload
from proficiency.models import Comparison, Device, MeasurementPoint

if TYPE_CHECKING:
    from analysis.core.signals.records import Record

NOMINAL = 418.0
REFERENCE_DATA = Path(settings.BASE_DIR) / "docs" / "reference-data"  # published tables
RAW_SECONDS = 8.0  # synthetic records generated at load time: small (~80 kB + 160 kB)
RAW_BIAS = 1.002  # the record's truth differs from the reported value by +0.2 %


# Table 1 of Chiominto et al. 2024 as shipped with the specification; the copy
# here is used only when the shared folder is absent (e.g. an installed wheel).
def table1() -> dict[tuple[str, str, str], tuple[float, float]]:
    """(bench, device, axis) -> (mean sensitivity, expanded uncertainty k=2) of Table 1."""
    text = (REFERENCE_DATA / "chiominto2024_table1.csv").read_text(encoding="utf-8")
    return {
        (r["bench"], r["device"], r["axis"]): (
            float(r["sensitivity"]),
            float(r["expanded_uncertainty"]),
        )
        for r in csv.DictReader(text.splitlines())
    }


def _offsets(point: MeasurementPoint, mean: float) -> float:
    """Deterministic per-point offset from the Table 1 mean; offsets sum to zero per bench.

    Linear: −δ, 0, +δ over 5/10/20 Hz with δ = 0.3 %; curvilinear: tangential
    −a, 0, +a (a = 0.2 %) and radial +b, 0, −b (b = 0.6 %) over 5/8/10 Hz, so the
    radial results scatter more, as in the study.
    """
    rank = {5.0: 0, 10.0: 1, 20.0: 2} if point.bench == "linear" else {5.0: 0, 8.0: 1, 10.0: 2}
    sign = rank[point.frequency_hz] - 1
    rel = {"vertical": 0.003, "tangential": 0.002, "radial": -0.006}[point.direction]
    return sign * rel * mean


def reproduction_results(
    points: list[MeasurementPoint], bench: str
) -> list[tuple[MeasurementPoint, float, float]]:
    """Results of one bench lab that aggregate (docs/domain.md §3) exactly to Table 1.

    Within each (device, axis) the offsets have mean zero, so x̄ is the Table 1
    value; every result gets the same u_i = √(u_T1² − s²), so that
    √(ū² + s²) = u_T1 = U/2.
    """
    t1 = table1()
    by_cell: dict[tuple[str, str], list[MeasurementPoint]] = {}
    for p in points:
        if p.bench == bench:
            by_cell.setdefault((p.device.name, p.axis), []).append(p)
    out = []
    for (device, axis), cell in by_cell.items():
        mean, expanded = t1[(bench, device, axis)]
        values = np.array([mean + _offsets(p, mean) for p in cell])
        s = float(np.std(values, ddof=1))
        u_single = math.sqrt((expanded / 2) ** 2 - s**2)
        out += [(p, float(v), 2 * u_single) for p, v in zip(cell, values, strict=True)]
    return out


def synthetic_results(
    points: list[MeasurementPoint], lab_index: int, outlier: bool, seed: int = 20240
) -> list[tuple[MeasurementPoint, float, float]]:
    """Plausible results: the two benches' mean as truth, lab bias ~0.4 %, noise ~0.25 %
    (``seed``: one per round, so each round draws its own)."""
    t1 = table1()
    rng = np.random.default_rng(seed + lab_index)
    bias = rng.normal(0.0, 0.004)
    rel_u = rng.uniform(0.006, 0.012)  # standard uncertainty 0.6–1.2 %
    out = []
    for p in points:
        truth = 0.5 * (
            t1[("linear", p.device.name, p.axis)][0] + t1[("curvilinear", p.device.name, p.axis)][0]
        )
        value = truth * (1 + bias + rng.normal(0.0, 0.0025))
        if outlier and p.device.name == "MEMS 2":
            value *= 1.06
        out.append((p, round(value, 2), round(2 * rel_u * value, 2)))
    return out


def demo_devices(
    comparison: Comparison, numbers: tuple[int, ...], serial: str = "LSM6DSR-DEMO"
) -> list[Device]:
    """The demo's LSM6DSR devices ``MEMS <number>`` of ``comparison``, made once."""
    return [
        Device.objects.get_or_create(
            comparison=comparison,
            name=f"MEMS {i}",
            defaults={
                "model": "LSM6DSR",
                "serial": f"{serial}-{i:03d}",
                "nominal_sensitivity": NOMINAL,
                "tolerance": 1.0,
                "tolerance_relative": True,
                "tolerance_distribution": "rectangular",
            },
        )[0]
        for i in numbers
    ]


def submit(
    participant: Participant,
    rows: list[tuple[MeasurementPoint, float, float]],
    source: str,
    submitted: dt.datetime = dt.datetime(2024, 6, 15, 12, 0, tzinfo=dt.UTC),
    decided_after: dt.timedelta = dt.timedelta(days=16, hours=-3),
) -> None:
    """``participant``'s accepted version 1 of ``rows`` (point, value, U with k = 2), each
    value in its point's unit; a participant that has a submission keeps it."""
    if participant.submissions.exists():
        return
    submission = Submission.objects.create(
        participant=participant,
        version=1,
        status=Submission.Status.ACCEPTED,
        source=source,
        submitted_at=submitted,
        decided_at=submitted + decided_after,
    )
    Result.objects.bulk_create(
        Result(
            submission=submission,
            measurement_point=point,
            value=value,
            unit=point_unit(point.quantity, point.device.unit),
            expanded_uncertainty=expanded,
            coverage_factor=2.0,
        )
        for point, value, expanded in rows
    )


def raw_records(participant: Participant) -> None:
    """A synthetic linear (int16 + sidecar) and curvilinear (int16 + encoder CSV) record
    behind MEMS 1, X, 10 Hz, whose truth is the reported value × ``RAW_BIAS``; recomputed
    by the Celery task after the loader's transaction commits."""
    if participant.raw_records.exists():
        return
    submission = participant.submissions.get(version=1)
    for bench, direction in (("linear", "vertical"), ("curvilinear", "tangential")):
        result = submission.results.select_related("measurement_point__device").get(
            measurement_point__device__name="MEMS 1", measurement_point__axis="X",
            measurement_point__frequency_hz=10.0, measurement_point__bench=bench,
            measurement_point__direction=direction,
        )  # fmt: skip
        p = result.measurement_point
        truth = (result.value * RAW_BIAS, 419.0, 424.0)
        imp = synthetic.Imperfections(noise_digits=1.5, quantise=True, seed=11)
        point = p.key._asdict()
        if bench == "linear":
            mems = synthetic.linear_record(truth, duration=RAW_SECONDS, imp=imp)
            reference = None
        else:
            mems, enc = synthetic.curvilinear_records(truth, duration=RAW_SECONDS, imp=imp)
            reference = Upload(_csv(enc), "demo-encoder.csv", {"fs_hz": enc.meta["fs_hz"]})
        data = Upload(_int16(mems), f"demo-{bench}.bin", _plain(mems.meta))
        raw_record_upload(participant=participant, point_fields=point, data=data,
                          reference=reference)  # fmt: skip


def _int16(record: Record) -> bytes:
    return np.ascontiguousarray(record.data.T).astype("<i2").tobytes()


def _csv(record: Record) -> bytes:
    rows = [",".join(record.channels)] + [f"{v:.9g}" for v in record.data[0]]
    return ("\n".join(rows) + "\n").encode()


def _plain(meta: dict) -> dict:
    return {k: list(v) if isinstance(v, tuple) else v for k, v in meta.items()}
