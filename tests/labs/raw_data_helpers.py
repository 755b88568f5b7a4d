"""Synthetic raw records of known truth as the bytes a laboratory would upload, and the
round they are uploaded to: a closed comparison whose participants reported at every point."""

from __future__ import annotations

import json
from collections.abc import Callable, Mapping
from contextlib import AbstractContextManager
from typing import Any

import numpy as np
from django.contrib.auth.models import User
from django.core.files.uploadedfile import SimpleUploadedFile
from rest_framework.test import APIClient

from analysis.core.signals.records import Record
from analysis.core.signals.synthetic import Imperfections, curvilinear_records, linear_record
from labs.models import Laboratory, Membership, Participant, RawRecomputation
from labs.services import api_key_create
from proficiency.models import Comparison, MeasurementPoint
from proficiency.services import measurement_points_generate
from tests.factories import (
    ComparisonFactory,
    DeviceFactory,
    MembershipFactory,
    ParticipantFactory,
    ResultFactory,
    SubmissionFactory,
)

TRUTH = (421.0, 419.0, 424.0)
CLEAN = Imperfections(noise_digits=1.5, quantise=True, seed=7)


def int16_bytes(record: Record) -> bytes:
    """Interleaved little-endian int16 (the MEMS output format, docs/interfaces.md §2)."""
    return np.ascontiguousarray(record.data.T).astype("<i2").tobytes()


def sidecar(record: Record, **extra: object) -> bytes:
    meta = {k: list(v) if isinstance(v, tuple) else v for k, v in record.meta.items()}
    return json.dumps(meta | extra).encode()


def csv_bytes(record: Record) -> bytes:
    lines = [",".join(record.channels)]
    lines += [",".join(f"{v:.9g}" for v in row) for row in record.data.T]
    return ("\n".join(lines) + "\n").encode()


def linear(duration: float = 20.0, **kw: object) -> Record:
    return linear_record(TRUTH, duration=duration, imp=CLEAN, **kw)  # type: ignore[arg-type]


def curvilinear(duration: float = 20.0) -> tuple[Record, Record]:
    return curvilinear_records(TRUTH, duration=duration, imp=CLEAN)


def upload_fields(
    record: Record, reference: Record | None = None, *, name: str = "dut.bin", **extra: object
) -> dict[str, SimpleUploadedFile]:
    """The upload's files: ``record`` in int16 with its sidecar (``extra`` merged in), and
    ``reference`` as CSV with its own sidecar where one is given."""
    fields = {
        "file": SimpleUploadedFile(name, int16_bytes(record)),
        "sidecar": SimpleUploadedFile(f"{name}.json", sidecar(record, **extra)),
    }
    if reference is not None:
        fields["reference_file"] = SimpleUploadedFile("ref.csv", csv_bytes(reference))
        fields["reference_sidecar"] = SimpleUploadedFile("ref.csv.json", sidecar(reference))
    return fields


def raw_round(
    code: str, device: str, *grids: Mapping[str, Any]
) -> tuple[Comparison, list[MeasurementPoint]]:
    """The closed custom comparison ``code`` of one ``device`` in D/(m/s^2) and its points:
    each grid the keyword arguments of ``measurement_points_generate``."""
    comparison = ComparisonFactory.create(code=code, status="closed", protocol="custom")
    dev = DeviceFactory.create(comparison=comparison, name=device, unit="D/(m/s^2)")
    points: list[MeasurementPoint] = []
    for grid in grids:
        points += measurement_points_generate(comparison=comparison, devices=[dev], **grid)
    return comparison, points


def reporting(
    comparison: Comparison,
    laboratory: Laboratory,
    code: str,
    points: list[MeasurementPoint],
    reported: tuple[float, float] | Mapping[str, tuple[float, float]],
) -> Participant:
    """``laboratory``'s participant ``code`` whose accepted version 1 reports (value, U with
    k = 2) at every point: ``reported``, or ``reported[point.quantity]`` given by kind."""
    part = ParticipantFactory.create(comparison=comparison, laboratory=laboratory, code=code)
    sub = SubmissionFactory.create(participant=part, version=1, status="accepted")
    for p in points:
        value, big_u = reported[p.quantity] if isinstance(reported, Mapping) else reported
        ResultFactory.create(submission=sub, measurement_point=p, value=value,
                             expanded_uncertainty=big_u, coverage_factor=2.0)  # fmt: skip
    return part


def staff(laboratory: Laboratory) -> User:
    """A new user who is ``laboratory``'s staff."""
    return MembershipFactory.create(laboratory=laboratory, role=Membership.Role.STAFF).user


def daq_key(laboratory: Laboratory) -> str:
    """A new API key of ``laboratory`` (its acquisition software's)."""
    return api_key_create(laboratory=laboratory, name="daq", user=None)[1]


def key_client(key: str) -> APIClient:
    client = APIClient()
    client.credentials(HTTP_AUTHORIZATION=f"Api-Key {key}")
    return client


def api_post(
    url: str, key: str, data: dict, capture: Callable[..., AbstractContextManager[object]]
) -> Any:
    """POST ``data`` with ``key``, the tasks sent on commit run (``capture``: pytest-django's
    ``django_capture_on_commit_callbacks``)."""
    with capture(execute=True):
        return key_client(key).post(url, data, format="multipart")


def axes(row: RawRecomputation) -> dict[str, dict]:
    """The recomputation's per-axis entries by axis name."""
    return {a["axis"]: a for a in row.axes}
