"""GUM conventions for results and tolerances (JCGM 100:2008), domain spec §2–§3.

Every function is vectorised: scalars and arrays broadcast with numpy rules and
the result is a float array of the broadcast shape (0-d for scalar input; use
``float()`` for a Python scalar).  Bad input raises :class:`CoreInputError`
naming the argument and the first offending (flattened) index.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from numpy.typing import ArrayLike

from analysis.core.groups import CoreInputError, FloatArray, as_finite
from analysis.core.lazy import stats  # scipy.stats on first use: 0.5 s of start-up

G_N = 9.80665
"""Standard acceleration of gravity g_n in m/s² (CGPM 1901, exact)."""

Distribution = Literal["rectangular", "normal", "triangular", "u-shaped"]

# Divisor turning a tolerance half-width a into a standard uncertainty
# (JCGM 100:2008 4.3.7 rectangular, 4.3.9 triangular; JCGM 101 6.4.6 arcsine).
_DIVISORS: dict[str, float] = {
    "rectangular": float(np.sqrt(3.0)),
    "triangular": float(np.sqrt(6.0)),
    "u-shaped": float(np.sqrt(2.0)),
}


def _checked(name: str, values: ArrayLike, *, positive: bool = False) -> FloatArray:
    """``as_finite`` that keeps the input's shape (scalars stay 0-d)."""
    arr = np.asarray(values, dtype=np.float64)
    return as_finite(name, arr, positive=positive).reshape(arr.shape)


def standard_from_expanded(U: ArrayLike, k: ArrayLike = 2.0) -> FloatArray:
    """Standard uncertainty u = U / k (JCGM 100:2008 6.2.1); U > 0 and k > 0."""
    return _checked("U", U, positive=True) / _checked("k", k, positive=True)


def expanded_from_standard(u: ArrayLike, k: ArrayLike = 2.0) -> FloatArray:
    """Expanded uncertainty U = k · u (JCGM 100:2008 6.2.1); u > 0 and k > 0."""
    return _checked("u", u, positive=True) * _checked("k", k, positive=True)


def absolute_from_relative(value: ArrayLike, U_percent: ArrayLike) -> FloatArray:
    """Absolute uncertainty |value| · U% / 100 from a relative one in percent.

    The value must be finite and non-zero (a relative uncertainty of zero is
    meaningless) and U% > 0.
    """
    v = _checked("value", value)
    if (v == 0).any():
        i = int(np.flatnonzero(v.reshape(-1) == 0)[0])
        raise CoreInputError(f"value[{i}] is 0: a relative uncertainty needs a non-zero value")
    return np.abs(v) * _checked("U_percent", U_percent, positive=True) / 100.0


def u_from_tolerance(
    half_width: ArrayLike, distribution: Distribution = "rectangular", k: ArrayLike = 2.0
) -> FloatArray:
    """Standard uncertainty of a tolerance ±a (JCGM 100:2008 4.3.7–4.3.9).

    rectangular a/√3, triangular a/√6, u-shaped (arcsine) a/√2; ``normal``
    means the tolerance is an expanded uncertainty with coverage factor ``k``
    (u = a/k; ``k`` is ignored for the other distributions).
    Example (domain spec §3): 418 ± 1 % rectangular, a = 4.18, u = 2.41329.
    """
    a = _checked("half_width", half_width, positive=True)
    if distribution == "normal":
        return a / _checked("k", k, positive=True)
    if distribution not in _DIVISORS:
        raise CoreInputError(
            f"unknown distribution {distribution!r}: use rectangular, normal, triangular "
            "or u-shaped"
        )
    return a / _DIVISORS[distribution]


def coverage_factor(dof: ArrayLike, p: float = 0.95) -> FloatArray:
    """Coverage factor k_p = t_{(1+p)/2}(ν), the Student t quantile (JCGM 100:2008 G.3).

    ``dof`` may be non-integer (Welch–Satterthwaite) and ``np.inf``, which gives
    the normal quantile (1.959964 for p = 0.95).  ν must be > 0, 0 < p < 1.
    """
    nu = np.asarray(dof, dtype=np.float64)
    flat = nu.reshape(-1)
    bad = np.isnan(flat) | ~(flat > 0)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise CoreInputError(f"dof[{i}] must be > 0 (or inf), got {flat[i]!r}")
    if not 0.0 < p < 1.0:
        raise CoreInputError(f"coverage probability p must be in (0, 1), got {p!r}")
    return np.asarray(stats.t.ppf(0.5 + p / 2.0, nu), dtype=np.float64)


def welch_satterthwaite(u_components: ArrayLike, dof_components: ArrayLike) -> FloatArray:
    """Effective degrees of freedom ν_eff = u_c⁴ / Σ(u_i⁴/ν_i) (JCGM 100:2008 G.4.1).

    ``u_components`` holds the standard-uncertainty contributions |c_i|·u(x_i):
    1-D for one quantity, or 2-D with one row per quantity and one column per
    component.  ``dof_components`` broadcasts against it; ν_i = inf (a Type B
    component known exactly) contributes nothing.  Returns one ν_eff per row
    (0-d for 1-D input); inf when every component has infinite ν.
    """
    u = np.asarray(u_components, dtype=np.float64)
    if u.ndim not in (1, 2) or u.shape[-1] == 0:
        raise CoreInputError("u_components must be a non-empty 1-D or 2-D array")
    flat = u.reshape(-1)
    bad = ~np.isfinite(flat) | (flat < 0)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise CoreInputError(f"u_components[{i}] must be finite and >= 0, got {flat[i]!r}")
    try:
        nu = np.broadcast_to(np.asarray(dof_components, dtype=np.float64), u.shape)
    except ValueError:
        raise CoreInputError(
            f"dof_components {np.shape(dof_components)} does not match u_components {u.shape}"
        ) from None
    coverage_factor(nu)  # validates ν > 0 with a clear message
    u_c2 = np.sum(u**2, axis=-1)
    if (u_c2 <= 0).any():
        row = int(np.flatnonzero(np.atleast_1d(u_c2) <= 0)[0])
        raise CoreInputError(f"quantity {row}: every uncertainty component is 0")
    denom = np.sum(np.where(np.isinf(nu), 0.0, u**4 / nu), axis=-1)
    with np.errstate(divide="ignore"):
        return np.asarray(np.where(denom > 0, u_c2**2 / denom, np.inf), dtype=np.float64)


def mg_per_lsb_to_digits_per_ms2(value: ArrayLike, U: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Inverted datasheet sensitivity in mg/LSB to D/(m/s²), domain spec §2.

    S = 1 / (value · 1e-3 · g_n); the relative uncertainty is kept,
    U_S = S · U / value.  0.244 mg/LSB → 417.9 D/(m/s²).
    """
    v = _checked("value", value, positive=True)
    big_u = _checked("U", U, positive=True)
    s = 1.0 / (v * 1e-3 * G_N)
    return s, s * big_u / v


def digits_per_ms2_to_mg_per_lsb(value: ArrayLike, U: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Sensitivity in D/(m/s²) to mg/LSB: the same reciprocal, relative U kept."""
    return mg_per_lsb_to_digits_per_ms2(value, U)
