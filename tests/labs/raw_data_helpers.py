"""Synthetic raw records of known truth as the bytes a laboratory would upload."""

from __future__ import annotations

import json

import numpy as np

from analysis.core.signals.records import Record
from analysis.core.signals.synthetic import Imperfections, curvilinear_records, linear_record

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
