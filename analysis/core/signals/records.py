"""Raw time-series records (docs/interfaces.md §2): CSV and little-endian int16 + JSON sidecar.

A record is a 2-D float array (one row per channel) plus its metadata.  Readers
validate the whole file with vectorised checks and raise :class:`SignalInputError`
naming the file, the line (CSV) or sample (binary) and the channel of the first
problem: truncated files, wrong channel counts, non-finite samples.  Samples at
the int16 rails (≥ 32767 or ≤ −32767) are counted per channel in
``Record.clipped``; the benches refuse to use a clipped channel.
"""

from __future__ import annotations

import io
import json
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from analysis.core.groups import CoreInputError, FloatArray
from common.sizes import counted

CHANNELS = ("x", "y", "z", "ref", "encoder_rad", "gx", "gy", "gz")
MEMS_AXES = ("x", "y", "z")
GYRO_AXES = ("gx", "gy", "gz")
"""Gyroscope channels: angular rate about the MEMS x, y, z axes (docs/domain.md §12.1)."""
INT16_RAIL = 32767
"""|sample| ≥ this is at the rail of a 16-bit output (+32767, −32767 or −32768)."""


class SignalInputError(CoreInputError):
    """A raw record or its metadata is unusable: says which file, where, and why."""


@dataclass(frozen=True)
class Record:
    """One raw record: ``data[i]`` holds the samples of ``channels[i]``.

    ``meta`` is the validated metadata (sidecar merged with overrides), ``t_s`` the
    optional time column of a CSV, ``clipped`` maps a channel to (number of samples
    at the int16 rail, index of the first one).
    """

    name: str
    channels: tuple[str, ...]
    data: FloatArray
    meta: dict[str, Any] = field(default_factory=dict)
    t_s: FloatArray | None = None
    clipped: dict[str, tuple[int, int]] = field(default_factory=dict)

    @property
    def n_samples(self) -> int:
        return int(self.data.shape[1])

    def channel(self, name: str) -> FloatArray:
        if name not in self.channels:
            raise SignalInputError(
                f"{self.name}: no channel {name!r} (channels: {', '.join(self.channels)})"
            )
        return self.data[self.channels.index(name)]

    def sampling_rate(self) -> tuple[float, bool]:
        """(rate in Hz, trusted?): ``fs_hz`` is trusted; ``fs_nominal_hz`` or the median
        step of ``t_s`` is only a starting value for estimating the actual rate."""
        if "fs_hz" in self.meta:
            return float(self.meta["fs_hz"]), True
        if "fs_nominal_hz" in self.meta:
            return float(self.meta["fs_nominal_hz"]), False
        if self.t_s is not None and self.t_s.size > 1:
            return float(1.0 / np.median(np.diff(self.t_s))), False
        raise SignalInputError(
            f"{self.name}: no sampling rate: give fs_hz or fs_nominal_hz, or a t_s column"
        )


_NUMBER_KEYS = {
    "fs_nominal_hz": True,
    "fs_hz": True,
    "full_scale_g": True,
    "frequency_hz": True,
    "a_ref_m_s2": True,
    "radius_m": True,
    "reference_radius_m": True,
    "oscillation_angle_deg": True,
    "tilt_deg": False,
    "rotation_deg": False,
    "gyro_full_scale_dps": True,
}  # key -> must be > 0
MAX_TIME_S = 1e10
"""Bound of the time keys (about 317 years): a clock time in seconds, never 1e308."""
_TIME_KEYS = {
    "trigger_offset_s": False,
    "start_time_s": False,
    "u_trigger_offset_s": True,
}  # key -> must be >= 0 (docs/interfaces.md §2, phase)
_CHOICES = {
    "unit": ("digits", "m/s^2"),
    "bench": ("linear", "curvilinear"),
    "gyro_unit": ("digits", "deg/s"),
}
_DIRECTIONS = ("tangential", "radial", "axial")


def parse_meta(raw: Mapping[str, Any], where: str) -> dict[str, Any]:
    """Validate metadata keys of docs/interfaces.md §2; unknown keys are kept as they are
    (but, like every key, never with a control character or a non-finite number)."""
    meta = dict(raw)
    for key, value in meta.items():
        _check_plain(value, f"{where}: {key}", str(key))
    for key, positive in _NUMBER_KEYS.items():
        if meta.get(key) is None:
            meta.pop(key, None)
            continue
        value = _number(meta[key], f"{where}: {key}")
        if positive and not value > 0:
            raise SignalInputError(f"{where}: {key} must be > 0, got {meta[key]!r}")
        meta[key] = value
    for key, non_negative in _TIME_KEYS.items():
        if meta.get(key) is not None:
            meta[key] = _bounded(meta[key], f"{where}: {key}", non_negative, MAX_TIME_S, "s")
    if meta.get("u_encoder_scale_rel") is not None:
        meta["u_encoder_scale_rel"] = _bounded(
            meta["u_encoder_scale_rel"], f"{where}: u_encoder_scale_rel", True, 1.0, ""
        )
    for key, allowed in _CHOICES.items():
        if key in meta and meta[key] not in allowed:
            raise SignalInputError(
                f"{where}: {key} must be one of {', '.join(allowed)}, got {meta[key]!r}"
            )
    if "channels" in meta:
        meta["channels"] = _channel_list(meta["channels"], where)
    if "orientation" in meta:
        meta["orientation"] = _orientation(meta["orientation"], where)
    if "zones" in meta:
        meta["zones"] = _zones(meta["zones"], where)
    return meta


#: a number as text: ASCII digits (float() also reads "1_0" and other scripts' digits), or
#: a word for a non-finite one, refused as such below
_NUMBER_TEXT = re.compile(
    r"\s*[+-]?(?:(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?|inf|infinity|nan)\s*", re.ASCII | re.I
)


def _number(value: Any, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float | str):
        raise SignalInputError(f"{what} must be a number, got {value!r}")
    if isinstance(value, str) and not _NUMBER_TEXT.fullmatch(value):
        raise SignalInputError(f"{what} must be a number, got {value!r}")
    try:
        out = float(value)
    except (ValueError, OverflowError):  # OverflowError: an int of more digits than a float
        raise SignalInputError(f"{what} must be a number, got {value!r}") from None
    if not np.isfinite(out):
        raise SignalInputError(f"{what} must be finite, got {value!r}")
    return out


_CONTROL = re.compile("[\x00-\x08\x0b\x0c\x0e-\x1f\ud800-\udfff]")
"""C0 characters no metadata text needs (NUL cannot even be stored by PostgreSQL), and lone
UTF-16 surrogates, which JSON can carry and PostgreSQL's jsonb refuses."""
MAX_DEPTH = 16
"""Nesting of a metadata value (the keys of docs/interfaces.md §2 nest two levels)."""


def _check_plain(value: Any, what: str, key: str = "", depth: int = 0) -> None:
    """Refuse a control character or a lone surrogate (in a key or a text), a non-finite
    number, or nesting deeper than :data:`MAX_DEPTH`, anywhere in a (nested) metadata value,
    naming the key's path."""
    for text in (key, value if isinstance(value, str) else ""):
        if found := _CONTROL.search(text):
            # a NUL or a surrogate in a key, escaped
            shown = what.encode("unicode_escape", "backslashreplace").decode("ascii")
            code = ord(found.group())
            kind = "lone surrogate" if code >= 0xD800 else "control character"
            raise SignalInputError(f"{shown} holds the {kind} U+{code:04X}")
    if isinstance(value, float) and not np.isfinite(value):
        raise SignalInputError(f"{what} must be finite, got {value!r}")
    if depth > MAX_DEPTH and isinstance(value, Mapping | list | tuple):
        raise SignalInputError(f"{what} is nested deeper than {MAX_DEPTH} levels")
    if isinstance(value, Mapping):
        for k, v in value.items():
            _check_plain(v, f"{what}.{k}", str(k), depth + 1)
    elif isinstance(value, list | tuple):
        for i, v in enumerate(value):
            _check_plain(v, f"{what}[{i}]", depth=depth + 1)


def _bounded(value: Any, what: str, non_negative: bool, bound: float, unit: str) -> float:
    """A finite number within ±bound (0..bound when ``non_negative``)."""
    out = _number(value, what)
    if non_negative and out < 0:
        raise SignalInputError(f"{what} must be >= 0, got {value!r}")
    if abs(out) > bound:
        raise SignalInputError(f"{what} must be within ±{bound:g} {unit}, got {value!r}".rstrip())
    return out


def _channel_list(value: Any, where: str) -> tuple[str, ...]:
    if not isinstance(value, list | tuple) or not value:
        raise SignalInputError(f"{where}: channels must be a non-empty list of names")
    names = tuple(str(v).strip().lower() for v in value)
    unknown = [n for n in names if n not in CHANNELS]
    if unknown:
        raise SignalInputError(
            f"{where}: unknown channel {unknown[0]!r} (known: {', '.join(CHANNELS)})"
        )
    if len(set(names)) != len(names):
        raise SignalInputError(f"{where}: channel names repeat: {', '.join(names)}")
    return names


def _orientation(value: Any, where: str) -> dict[str, str]:
    if not isinstance(value, Mapping):
        raise SignalInputError(f"{where}: orientation must map axes to directions")
    out = {str(k).lower(): str(v).lower() for k, v in value.items()}
    for axis, direction in out.items():
        if axis not in MEMS_AXES or direction not in _DIRECTIONS:
            raise SignalInputError(
                f"{where}: orientation {axis!r}: {direction!r} must map x/y/z to "
                f"{', '.join(_DIRECTIONS)}"
            )
    return out


def _zones(value: Any, where: str) -> dict[str, tuple[float, float]]:
    if not isinstance(value, Mapping):
        raise SignalInputError(f"{where}: zones must be an object of name -> [t0, t1]")
    out = {}
    for name, span in value.items():
        if not isinstance(span, list | tuple) or len(span) != 2:
            raise SignalInputError(f"{where}: zone {name!r} must be [t0, t1] in seconds")
        t0, t1 = (_number(v, f"{where}: zone {name!r}") for v in span)
        if not t1 > t0:
            raise SignalInputError(f"{where}: zone {name!r} ends before it starts: {span}")
        out[str(name)] = (t0, t1)
    return out


def read_csv(content: bytes, name: str, meta: Mapping[str, Any] | None = None) -> Record:
    """CSV with a header: optional ``t_s``, then one column per channel (docs/interfaces.md §2)."""
    text = content.decode("utf-8-sig", errors="strict")
    header, _, body = text.partition("\n")
    delim = ";" if ";" in header and "," not in header else ","
    columns = [c.strip().lower() for c in header.strip().split(delim)]
    has_t = columns[0] == "t_s"
    channels = _channel_list(columns[1:] if has_t else columns, f"{name} line 1 (header)")
    m = parse_meta(meta or {}, f"{name} metadata")
    if "channels" in m and m["channels"] != channels:
        raise SignalInputError(
            f"{name}: header has channels {', '.join(channels)} but the metadata says "
            f"{', '.join(m['channels'])}"
        )
    body = body.rstrip("\r\n")
    if not body.strip():
        raise SignalInputError(f"{name}: no samples after the header")
    _check_field_counts(body.encode(), delim, len(columns), columns, name)
    table = _loadtxt(body, delim, columns, name)
    t_s = table[:, 0].copy() if has_t else None
    data = np.ascontiguousarray(table[:, 1:].T if has_t else table.T)
    _check_finite(data, channels, name, lambda i: f"line {i + 2}")
    if t_s is not None:
        _check_finite(t_s[None, :], ("t_s",), name, lambda i: f"line {i + 2}")
        steps = np.diff(t_s)
        if (steps <= 0).any():
            i = int(np.flatnonzero(steps <= 0)[0]) + 1
            raise SignalInputError(f"{name} line {i + 2}: t_s does not increase ({t_s[i]!r})")
    digits = m.get("unit", "digits") == "digits"
    gyro_digits = m.get("gyro_unit", "digits") == "digits"
    return Record(name, channels, data, m, t_s, _clipped(data, channels, digits, gyro_digits))


def _check_field_counts(
    body: bytes, delim: str, n_cols: int, columns: list[str], name: str
) -> None:
    buf = np.frombuffer(body, dtype=np.uint8)
    ends = np.append(np.flatnonzero(buf == ord("\n")), buf.size)
    starts = np.concatenate(([0], ends[:-1] + 1))
    cum = np.concatenate(([0], np.cumsum(buf == ord(delim))))
    fields = cum[ends] - cum[starts] + 1
    bad = np.flatnonzero(fields != n_cols)
    if bad.size:
        i = int(bad[0])
        last = " (the last line: truncated file?)" if i == fields.size - 1 else ""
        raise SignalInputError(
            f"{name} line {i + 2}: {counted(int(fields[i]), 'field')}, expected {n_cols} "
            f"({', '.join(columns)}){last}"
        )


def _loadtxt(body: str, delim: str, columns: list[str], name: str) -> FloatArray:
    try:
        return np.loadtxt(io.StringIO(body), delimiter=delim, dtype=np.float64, ndmin=2)
    except ValueError as exc:
        m = re.search(r"string '(.*)' to float64 at row (\d+), column (\d+)", str(exc))
        if not m:
            raise SignalInputError(f"{name}: {exc}") from None
        row, col = int(m.group(2)), int(m.group(3))
        raise SignalInputError(
            f"{name} line {row + 2}, channel {columns[col - 1]}: not a number: {m.group(1)!r}"
        ) from None


def read_int16(content: bytes, name: str, meta: Mapping[str, Any]) -> Record:
    """Little-endian int16 samples interleaved channel by channel; ``meta['channels']``
    (from the JSON sidecar) gives their names in file order (docs/interfaces.md §2)."""
    m = parse_meta(meta, f"{name} sidecar")
    if "channels" not in m:
        raise SignalInputError(f"{name}: the sidecar must list 'channels' in file order")
    channels: tuple[str, ...] = m["channels"]
    n_ch = len(channels)
    if len(content) % 2:
        raise SignalInputError(
            f"{name}: {len(content)} bytes is not a whole number of int16 samples (truncated file?)"
        )
    samples = np.frombuffer(content, dtype="<i2")
    if samples.size == 0:
        raise SignalInputError(f"{name}: the file holds no samples")
    if samples.size % n_ch:
        rest = samples.size % n_ch
        raise SignalInputError(
            f"{name}: {samples.size} samples do not fill frames of {n_ch} channels "
            f"({', '.join(channels)}): the last frame (sample {samples.size // n_ch}) has "
            f"{rest} of {n_ch} values, channel {channels[rest]} missing (truncated file, or "
            "wrong 'channels' in the sidecar?)"
        )
    data = np.ascontiguousarray(samples.reshape(-1, n_ch).T, dtype=np.float64)
    return Record(name, channels, data, m, None, _clipped(data, channels, True, True))


def _check_finite(data: FloatArray, channels: tuple[str, ...], name: str, where: Any) -> None:
    bad = ~np.isfinite(data)
    if bad.any():
        ch, i = np.argwhere(bad.T)[0][::-1]
        raise SignalInputError(
            f"{name} {where(int(i))}, channel {channels[int(ch)]}: non-finite sample "
            f"{float(data[ch, i])!r} ({int(bad.sum())} in the file)"
        )


def _clipped(
    data: FloatArray, channels: tuple[str, ...], digits: bool, gyro_digits: bool
) -> dict[str, tuple[int, int]]:
    """Samples at the int16 rails, per MEMS axis (and gyroscope) channel whose unit is
    digits."""
    railed = (MEMS_AXES if digits else ()) + (GYRO_AXES if gyro_digits else ())
    rail = np.abs(data) >= INT16_RAIL
    counts = rail.sum(axis=1)
    first = rail.argmax(axis=1)
    return {
        ch: (int(counts[i]), int(first[i]))
        for i, ch in enumerate(channels)
        if counts[i] and ch in railed
    }


def load_record(
    path: Path, sidecar: Path | None = None, overrides: Mapping[str, Any] | None = None
) -> Record:
    """Read ``path`` (``.csv``: CSV; anything else: int16) with the sidecar ``path.json``
    or the one given; ``overrides`` (e.g. command-line options) replace sidecar keys."""
    if not path.is_file():
        raise SignalInputError(f"{path}: no such file")
    meta = read_sidecar(sidecar or Path(f"{path}.json"), required=sidecar is not None)
    meta.update({k: v for k, v in (overrides or {}).items() if v is not None})
    if path.suffix.lower() == ".csv":
        return read_csv(path.read_bytes(), path.name, meta)
    if "channels" not in meta:
        raise SignalInputError(
            f"{path.name}: a binary record needs its JSON sidecar ({path.name}.json) "
            "listing 'channels'"
        )
    return read_int16(path.read_bytes(), path.name, meta)


def json_document(content: bytes, where: str) -> Any:
    """A sidecar's JSON (UTF-8, BOM allowed); SignalInputError naming ``where`` for what is
    not valid JSON, an integer longer than Python converts (4,300 digits) or nesting deeper
    than the parser's stack (a RecursionError was a 500)."""
    try:
        return json.loads(content.decode("utf-8-sig"))
    except ValueError as exc:  # JSONDecodeError, UnicodeDecodeError, the digits limit
        raise SignalInputError(f"{where}: not valid JSON: {exc}") from None
    except RecursionError:
        raise SignalInputError(f"{where}: not valid JSON: nested too deeply") from None


def read_sidecar(path: Path, *, required: bool) -> dict[str, Any]:
    if not path.is_file():
        if required:
            raise SignalInputError(f"{path}: no such sidecar file")
        return {}
    doc = json_document(path.read_bytes(), path.name)
    if not isinstance(doc, dict):
        raise SignalInputError(f"{path.name}: the sidecar must be a JSON object")
    return doc
