"""Vibration robustness figures (docs/domain.md §8.3; IEC 60068-2-80 sine-on-random).

Per repetition, with zones before / test / after and j the excited axis:

    RR_ij = |20·log10(RMS_i,test / RMS_j,test)|    i not excited   (ideal → ∞)
    SR_ij = |20·log10(RMS_i,test / RMS_i,before)|  i not excited   (ideal → 0)
    SNR   = MATLAB snr(x, fs, 6) of each axis in the test zone     (:mod:`.snr`)

RMS is taken of the AC part (mean removed): the static gravity component would
otherwise dominate the vertical axis.  Before/after: the mean of each axis is
compatible when En = |m_after − m_before| / (2·√(s_b² + s_a²)) ≤ 1 (each zone's
standard deviation taken as the standard uncertainty of a reading, k = 2); the
standard deviations when F = s_a²/s_b² lies inside the two-sided 95 % F interval with
n − 1 degrees of freedom.  Across repetitions: mean ± sample sd (ddof = 1).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike
from scipy import stats

from analysis.core.groups import FloatArray
from analysis.core.signals.records import Record, SignalInputError
from analysis.core.signals.snr import snr_db

ZONES = ("before", "test", "after")


def zone_slices(
    record: Record, zones: Mapping[str, tuple[float, float]], fs_hz: float
) -> dict[str, slice]:
    """Sample ranges of each zone [t0, t1) s, from ``t_s`` when the record has it."""
    t = record.t_s if record.t_s is not None else np.arange(record.n_samples) / fs_hz
    out = {}
    for name, (t0, t1) in zones.items():
        lo, hi = (int(v) for v in np.searchsorted(t, [t0, t1]))
        if hi - lo < 2:
            raise SignalInputError(
                f"{record.name}: zone {name!r} [{t0:g}, {t1:g}] s holds "
                f"{hi - lo} samples (record: {t[0]:g}–{t[-1]:g} s)"
            )
        out[name] = slice(lo, hi)
    return out


def ac_rms(y: ArrayLike) -> FloatArray:
    """RMS of each row with its mean removed."""
    arr = np.atleast_2d(np.asarray(y, dtype=np.float64))
    return np.asarray(arr.std(axis=1), dtype=np.float64)


def db_ratio(a: ArrayLike, b: ArrayLike) -> FloatArray:
    """|20·log10(a / b)|."""
    return np.asarray(np.abs(20.0 * np.log10(np.asarray(a) / np.asarray(b))), dtype=np.float64)


@dataclass(frozen=True)
class Repetition:
    """Figures of one repetition; arrays have one entry per axis (NaN where undefined)."""

    axes: tuple[str, ...]
    excited: str
    rms: dict[str, FloatArray]
    rr_db: FloatArray
    sr_db: FloatArray
    snr_db: FloatArray
    mean: dict[str, FloatArray]
    sd: dict[str, FloatArray]
    en_mean: FloatArray
    f_ratio: FloatArray
    sd_compatible: np.ndarray

    def to_dict(self) -> dict[str, Any]:
        def per_axis(v: FloatArray) -> dict[str, float | None]:
            return {
                a.upper(): (None if np.isnan(x) else float(x))
                for a, x in zip(self.axes, v, strict=True)
            }

        return {
            "excited_axis": self.excited.upper(),
            "rms": {z: per_axis(v) for z, v in self.rms.items()},
            "rr_db": per_axis(self.rr_db),
            "sr_db": per_axis(self.sr_db),
            "snr_db": per_axis(self.snr_db),
            "before_after": {
                a.upper(): {
                    "mean_before": float(self.mean["before"][i]),
                    "sd_before": float(self.sd["before"][i]),
                    "mean_after": float(self.mean["after"][i]),
                    "sd_after": float(self.sd["after"][i]),
                    "en_mean": float(self.en_mean[i]),
                    "mean_compatible": bool(self.en_mean[i] <= 1),
                    "f_ratio": float(self.f_ratio[i]),
                    "sd_compatible": bool(self.sd_compatible[i]),
                }
                for i, a in enumerate(self.axes)
            },
        }


def repetition(
    before: FloatArray,
    test: FloatArray,
    after: FloatArray,
    axes: Sequence[str],
    excited: str,
    fs_hz: float,
    n_harmonics: int = 6,
) -> Repetition:
    """Figures of one repetition from the three zones, each (axes, samples)."""
    axes = tuple(a.lower() for a in axes)
    if excited.lower() not in axes:
        raise SignalInputError(f"excited axis {excited!r} is not among {', '.join(axes)}")
    j = axes.index(excited.lower())
    zones = {
        "before": np.atleast_2d(before),
        "test": np.atleast_2d(test),
        "after": np.atleast_2d(after),
    }
    for name, z in zones.items():
        if z.shape[0] != len(axes):
            raise SignalInputError(f"zone {name}: {z.shape[0]} channels, expected {len(axes)}")
    rms = {name: ac_rms(z) for name, z in zones.items()}
    for name, values in rms.items():
        if (values == 0).any():
            axis = axes[int(np.flatnonzero(values == 0)[0])]
            raise SignalInputError(
                f"zone {name}, axis {axis}: constant signal (RMS 0): sensor "
                "stuck, or the wrong channel?"
            )
    others = np.arange(len(axes)) != j
    rr = np.where(others, db_ratio(rms["test"], rms["test"][j]), np.nan)
    sr = np.where(others, db_ratio(rms["test"], rms["before"]), np.nan)
    mean = {k: zones[k].mean(axis=1) for k in ("before", "after")}
    sd = {k: zones[k].std(axis=1, ddof=1) for k in ("before", "after")}
    en = np.abs(mean["after"] - mean["before"]) / (2 * np.hypot(sd["before"], sd["after"]))
    f_ratio = sd["after"] ** 2 / sd["before"] ** 2
    dfa, dfb = zones["after"].shape[1] - 1, zones["before"].shape[1] - 1
    lo, hi = stats.f.ppf([0.025, 0.975], dfa, dfb)
    return Repetition(
        axes,
        axes[j],
        rms,
        rr,
        sr,
        snr_db(zones["test"], fs_hz, n_harmonics),
        mean,
        sd,
        en,
        f_ratio,
        (f_ratio >= lo) & (f_ratio <= hi),
    )


def summary(reps: Sequence[Repetition]) -> dict[str, dict[str, dict[str, float | None]]]:
    """Mean ± sd (ddof = 1) across repetitions of RR, SR and SNR per axis (Tables V–VII)."""
    if not reps:
        raise SignalInputError("no repetition to summarise")
    out: dict[str, dict[str, dict[str, float | None]]] = {}
    for key in ("rr_db", "sr_db", "snr_db"):
        table = np.stack([getattr(r, key) for r in reps])  # (reps, axes)
        out[key] = {}
        for i, axis in enumerate(reps[0].axes):
            col = table[:, i][~np.isnan(table[:, i])]
            out[key][axis.upper()] = {
                "mean": float(col.mean()) if col.size else None,
                "sd": float(col.std(ddof=1)) if col.size > 1 else None,
                "n": int(col.size),
            }
    return out
