"""Raw records on the Django side: metadata from form fields and sidecars, reading bytes
into :class:`~analysis.core.signals.records.Record`, and the record-with-fit figure.

The numerics are ``analysis.core.signals``'; this module only adapts uploads and stored
files to its readers (docs/interfaces.md §2) and draws the figure (matplotlib, Agg backend).
"""

from __future__ import annotations

import io
from collections.abc import Mapping
from typing import Any

import matplotlib

matplotlib.use("Agg")

import numpy as np
from matplotlib.figure import Figure

from analysis.core.signals.records import (
    Record,
    SignalInputError,
    json_document,
    read_csv,
    read_int16,
)
from analysis.core.signals.sinefit import centred_index, fit_known_frequency
from common.errors import RequestTooLarge
from labs.importers.values import human_size

#: form fields that are metadata keys (docs/interfaces.md §2); lists and objects come as JSON
META_NUMBERS = (
    "fs_nominal_hz", "fs_hz", "full_scale_g", "a_ref_m_s2", "tilt_deg", "rotation_deg",
    "radius_m", "reference_radius_m", "oscillation_angle_deg", "trigger_offset_s",
    "u_trigger_offset_s", "start_time_s", "gyro_full_scale_dps", "u_encoder_scale_rel",
)  # fmt: skip
META_TEXT = ("unit", "gyro_unit")
META_JSON = ("orientation", "zones")
PLOT_PERIODS = 4
PLOT_HARMONICS = (1, 2, 3)


def sidecar_json(content: bytes, where: str) -> dict[str, Any]:
    """A JSON sidecar's object; SignalInputError naming ``where`` otherwise."""
    doc = json_document(content, where)
    if not isinstance(doc, dict):
        raise SignalInputError(f"{where}: must be a JSON object of metadata keys")
    return doc


def form_metadata(fields: Mapping[str, Any]) -> dict[str, Any]:
    """Metadata keys given as form fields; empty fields are left out."""
    meta: dict[str, Any] = {}
    for key in (*META_NUMBERS, *META_TEXT):
        if fields.get(key) not in (None, ""):
            meta[key] = fields[key]
    for key in META_JSON:
        if fields.get(key) not in (None, ""):
            meta[key] = _json_field(fields[key], key)
    channels = fields.get("channels")
    if channels not in (None, ""):
        text = str(channels).strip()
        meta["channels"] = (
            _json_field(text, "channels") if text.startswith("[") else text.split(",")
        )
    return meta


def _json_field(value: Any, key: str) -> Any:
    if not isinstance(value, str):
        return value
    return json_document(value.encode("utf-8", "surrogatepass"), key)


def read_record(content: bytes, name: str, meta: Mapping[str, Any]) -> Record:
    """CSV when the name ends in ``.csv``, int16 little-endian otherwise (docs/interfaces.md §2)."""
    if name.lower().endswith(".csv"):
        return read_csv(content, name, meta)
    if "channels" not in meta:
        raise SignalInputError(
            f"{name}: a binary record needs its metadata (a sidecar or the channels field) "
            "listing 'channels' in file order"
        )
    return read_int16(content, name, meta)


def fit_figure_svg(record: Record, axis: str, frequency_hz: float, fs_hz: float) -> str:
    """SVG of the first ``PLOT_PERIODS`` periods of channel ``axis`` with the three-
    parameter sine fit (IEEE 1057 §8.5, harmonics 1–3) at ν = f / fs over that stretch."""
    y = record.channel(axis)
    nu = frequency_hz / fs_hz
    n = min(y.size, max(16, round(PLOT_PERIODS / nu)))
    stretch = y[:n]
    fit = fit_known_frequency(stretch, nu, PLOT_HARMONICS)
    model = _model(fit.amplitude[0], fit.phase[0], float(fit.offset[0]), nu, n)
    t_ms = np.arange(n) / fs_hz * 1e3
    # a Figure of its own, not pyplot's global figure registry: the web workers are threaded
    fig = Figure(figsize=(7.0, 2.6), dpi=100)
    ax = fig.subplots()
    ax.plot(t_ms, stretch, ".", ms=2.5, color="#6c757d", label=f"{axis.upper()} samples")
    ax.plot(t_ms, model, "-", lw=1.2, color="#0d6efd", label="fitted sine (f, 2f, 3f)")
    ax.set_xlabel("time (ms)")
    ax.set_ylabel(record.meta.get("unit", "digits"))
    ax.legend(loc="upper right", fontsize=8, frameon=False)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    buf = io.StringIO()
    fig.savefig(buf, format="svg")
    svg = buf.getvalue()
    return svg[svg.index("<svg") :]


def _model(amp: np.ndarray, phase: np.ndarray, offset: float, nu: float, n: int) -> np.ndarray:
    """Reconstruct the fit; the same convention as the fit's own residuals (checked by a
    test: the model must match the samples of a clean record)."""
    k = centred_index(n)
    out = np.full(n, offset)
    for h, a, p in zip(PLOT_HARMONICS, amp, phase, strict=True):
        out = out + a * np.cos(2 * np.pi * h * nu * k + p)
    return out


class RawUploadLimit:
    """Upload handler (put first) that stops a multipart body as soon as one file in it
    passes ``limit`` bytes: the limit holds also when Content-Length is absent or lies.
    Raises :class:`~common.errors.RequestTooLarge` (413)."""

    chunk_size = 64 * 1024

    def __init__(self, request: Any = None, *, limit: int) -> None:
        self.request = request
        self.limit = limit
        self.received = 0
        self.name = ""

    def handle_raw_input(self, *args: Any, **kwargs: Any) -> None:
        return None

    def new_file(self, field_name: str, file_name: str, *args: Any, **kwargs: Any) -> None:
        self.received, self.name = 0, file_name

    def receive_data_chunk(self, raw_data: bytes, start: int) -> bytes:
        self.received += len(raw_data)
        if self.received > self.limit:
            raise RequestTooLarge(
                f"The file {self.name!r} is larger than the limit for raw records "
                f"({human_size(self.limit)}); nothing was stored."
            )
        return raw_data

    def file_complete(self, file_size: int) -> None:
        return None

    def upload_complete(self) -> None:
        return None

    def upload_interrupted(self) -> None:
        return None
