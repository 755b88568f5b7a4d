"""Performance statistics of ISO 13528:2022 Clause 9 (domain spec §4), vectorised.

All results of a round are scored at once: flat per-result arrays plus a
:class:`Groups` mapping each result to its measurement point, and per-group
assigned values.  Flags are small integer codes, see :data:`FLAG_LABELS`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from analysis.core.groups import BoolArray, CoreInputError, FloatArray, Groups, as_finite

FLAG_SATISFACTORY = 0
FLAG_WARNING = 1
FLAG_ACTION = 2
FLAG_NOT_SCORED = 3
FLAG_LABELS: tuple[str, ...] = ("satisfactory", "warning", "action", "not scored")
"""Label of each flag code: ``FLAG_LABELS[code]``."""

NEGLIGIBLE_FRACTION = 0.3
"""ISO 13528:2022 9.2.1, Formula (10): u(x_pt) is negligible when ≤ 0.3 σ_pt."""

FlagArray = NDArray[np.int8]

# Relative tolerance below which u²(x) − u²(x_pt) counts as "not positive":
# a single contributing result gives exactly 0 up to rounding.
_CORRELATION_RTOL = 1e-9


@dataclass(frozen=True)
class Scores:
    """Scores of every result (ISO 13528:2022 9.3–9.7) and their flags.

    Per result: ``d``, ``d_percent``, ``z``, ``z_prime``, ``zeta``, ``en``,
    ``u_d``/``U_d`` (the standard/expanded uncertainty of D used for ζ/En),
    ``performance`` (z or z′ per ``use_z_prime``), the ``*_flag`` codes,
    ``correlation_applied`` (Cox 2002 correction used) and
    ``correlation_failed`` (correction requested but u²(x) − u²(x_pt) ≤ 0, so
    the uncorrected sum was used instead).  Per group: ``use_z_prime``.
    z, z′ and ``performance`` are NaN, flagged "not scored", exactly where σ_pt
    is unknown; ``d_flag`` is "not scored" where δ_E is unknown.
    """

    d: FloatArray
    d_percent: FloatArray
    z: FloatArray
    z_prime: FloatArray
    zeta: FloatArray
    en: FloatArray
    u_d: FloatArray
    U_d: FloatArray
    performance: FloatArray
    d_flag: FlagArray
    z_flag: FlagArray
    z_prime_flag: FlagArray
    zeta_flag: FlagArray
    en_flag: FlagArray
    performance_flag: FlagArray
    use_z_prime: BoolArray
    correlation_applied: BoolArray
    correlation_failed: BoolArray


@dataclass(frozen=True)
class CombinedScore:
    """A score combined over rounds (RSZ or RLP), one entry per participant."""

    value: FloatArray
    n_rounds: NDArray[np.intp]
    flag: FlagArray


def flag_z(score: ArrayLike) -> FlagArray:
    """ISO 13528:2022 9.4.2 for z, z′, ζ: |s| ≤ 2 satisfactory, 2 < |s| < 3 warning,
    |s| ≥ 3 action; NaN → not scored."""
    a = np.abs(np.asarray(score, dtype=np.float64))
    out = (a > 2.0).view(np.int8) + (a >= 3.0).view(np.int8)  # 0, 1 or 2 without branches
    nan = np.isnan(a)
    if nan.any():
        out[nan] = FLAG_NOT_SCORED
    return out


def flag_en(score: ArrayLike, limit: float = 1.0) -> FlagArray:
    """En flag, domain spec §4: |En| ≤ limit satisfactory, otherwise action.

    (ISO 13528:2022 9.7.2 signals at |En| ≥ 1; the service follows the
    calibration convention |En| ≤ 1 = compatible.)
    """
    a = np.abs(np.asarray(score, dtype=np.float64))
    return (~(a <= limit)).view(np.int8) * np.int8(FLAG_ACTION)


def _group_array(name: str, values: ArrayLike, n: int) -> FloatArray:
    """One float per group: a scalar is broadcast, any other length is an error."""
    arr = np.asarray(values, dtype=np.float64)
    if arr.ndim > 1 or (arr.ndim == 1 and arr.size != n):
        raise CoreInputError(f"{name} needs a scalar or one value per group ({n}), got {arr.shape}")
    return np.broadcast_to(arr, (n,)).copy()


def _per_group(name: str, values: ArrayLike | None, n: int, *, allow_nan: bool) -> FloatArray:
    """Broadcast a per-group argument to ``n`` groups; NaN means "unknown" if allowed."""
    if values is None:
        return np.full(n, np.nan)
    arr = _group_array(name, values, n)
    bad = ~np.isfinite(arr) | (arr <= 0)
    if allow_nan:
        bad &= ~np.isnan(arr)
    if bad.any():
        g = int(np.flatnonzero(bad)[0])
        need = "> 0 and finite (NaN = unknown)" if allow_nan else "> 0 and finite"
        raise CoreInputError(f"{name} of group {g} must be {need}, got {arr[g]!r}")
    return arr


def _nonneg_per_group(name: str, values: ArrayLike, n: int) -> FloatArray:
    arr = as_finite(name, _group_array(name, values, n))
    if (arr < 0).any():
        g = int(np.flatnonzero(arr < 0)[0])
        raise CoreInputError(f"{name} of group {g} must be >= 0, got {arr[g]!r}")
    return arr


def _assigned(
    groups: Groups,
    x_pt: ArrayLike,
    u_pt: ArrayLike,
    U_pt: ArrayLike | None,
    k_pt: float,
    relative: BoolArray,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    n = groups.n_groups
    xp = as_finite("x_pt", _group_array("x_pt", x_pt, n))
    if ((xp == 0) & relative).any():
        g = int(np.flatnonzero((xp == 0) & relative)[0])
        raise CoreInputError(f"x_pt of group {g} is 0: D% = 100·D/x_pt is undefined")
    up = _nonneg_per_group("u(x_pt)", u_pt, n)
    if U_pt is not None:
        return xp, up, _nonneg_per_group("U(x_pt)", U_pt, n)
    if not (np.isfinite(k_pt) and k_pt > 0):
        raise CoreInputError(f"k_pt must be finite and > 0, got {k_pt!r}")
    return xp, up, k_pt * up


K_CORRELATED = 2.0
"""Coverage factor of U(d) for a result inside the assigned value (Cox 2002, §5: the
corrected u(d) is expanded with k = 2, whatever k the laboratory reported for U)."""


def _uncertainty_of_d(
    u: FloatArray, big_u: FloatArray, u_pt: FloatArray, big_u_pt: FloatArray, corr: BoolArray
) -> tuple[FloatArray, FloatArray, BoolArray, BoolArray]:
    """u(d) and U(d), one rule for every coverage factor.

    * A result outside the assigned value (``corr`` false): u²(d) = u² + u²(x_pt) and
      U²(d) = U² + U²(x_pt), each U as reported with its own k (ISO 13528:2022 9.6, 9.7,
      Formulae 19 and 20).
    * A result inside it (weighted mean, largest consistent subset, the reference
      laboratory itself): x_pt and x are correlated, so u²(d) = u² − u²(x_pt) and
      U(d) = 2·u(d) (Cox 2002, Metrologia 39:589, §5). The correction is made on
      *standard* uncertainties: subtracting expanded ones would mix coverage factors
      (k = 2.13 for U(x) and 2 for U(x_pt)) and can go negative for k = 1 input.

    Where u² − u²(x_pt) is not positive (the result is the sole contributor, or u(x_pt)
    carries more than the weighted-mean uncertainty) there is nothing to correct with:
    the result keeps the uncorrected sums and is reported in ``correlation_failed``, so
    a whole round is still scored and each such result is named.
    """
    u2, u2_pt = u * u, u_pt * u_pt
    if not corr.any():  # the common case (independent x_pt): plain sums
        return np.sqrt(u2 + u2_pt), np.hypot(big_u, big_u_pt), corr, corr.copy()
    u2_corr = u2 - u2_pt
    failed = corr & (u2_corr <= _CORRELATION_RTOL * u2)
    applied = corr & ~failed
    u_d = np.sqrt(np.where(applied, u2_corr, u2 + u2_pt))
    big_d = np.where(applied, K_CORRELATED * u_d, np.hypot(big_u, big_u_pt))
    return u_d, big_d, applied, failed


def compute_scores(
    x: ArrayLike,
    u: ArrayLike,
    U: ArrayLike,
    groups: Groups,
    x_pt: ArrayLike,
    u_pt: ArrayLike,
    *,
    U_pt: ArrayLike | None = None,
    k_pt: float = 2.0,
    sigma_pt: ArrayLike | None = None,
    contributes: ArrayLike | None = None,
    en_limit: float = 1.0,
    delta_e: ArrayLike | None = None,
    relative: ArrayLike | None = None,
) -> Scores:
    """D, D%, z, z′, ζ and En of ISO 13528:2022 9.3–9.7 (Formulae 11, 12, 14, 15, 19, 20).

    ``relative`` (per group, default every group) says where D% applies: not for a
    phase (docs/domain.md §12), whose D% is NaN and whose x_pt may be 0.

    ``x``, ``u``, ``U`` (> 0) and ``contributes`` are per result; ``x_pt``,
    ``u_pt`` (≥ 0), ``U_pt`` (default ``k_pt``·u_pt), ``sigma_pt`` and
    ``delta_e`` are per group (scalars broadcast; NaN or None = unknown for
    σ_pt and δ_E).  ``U_pt`` is U(x_pt) as its source gives it: a reference laboratory's
    U with its own k (pass it), 2·u(x_pt) for a consensus.  ``contributes`` marks results
    that entered the assigned value: ζ and En then use the Cox 2002 correction on standard
    uncertainties (see ``_uncertainty_of_d``).
    z is used where u(x_pt) ≤ 0.3 σ_pt (9.2.1), else z′ (9.5).  x_pt = 0 raises
    since D% is undefined.
    """
    xs = as_finite("x", x)
    us = as_finite("u(x)", u, positive=True)
    big_u = as_finite("U(x)", U, positive=True)
    if not (xs.size == us.size == big_u.size == groups.size):
        raise CoreInputError(
            f"x, u, U and groups must have one entry per result: got {xs.size}, {us.size}, "
            f"{big_u.size}, {groups.size}"
        )
    if not (np.isfinite(en_limit) and en_limit > 0):
        raise CoreInputError(f"en_limit must be finite and > 0, got {en_limit!r}")
    rel = np.ones(groups.n_groups, dtype=bool) if relative is None else np.asarray(relative)
    if rel.dtype != np.bool_ or rel.shape != (groups.n_groups,):
        raise CoreInputError(f"relative must be one boolean per group ({groups.n_groups})")
    xp, up, big_up = _assigned(groups, x_pt, u_pt, U_pt, k_pt, rel)
    sigma = _per_group("sigma_pt", sigma_pt, groups.n_groups, allow_nan=True)
    de = _per_group("delta_e", delta_e, groups.n_groups, allow_nan=True)
    corr = _contributes(contributes, groups.size)
    idx = groups.index
    d = xs - xp[idx]
    u_d, big_d, applied, failed = _uncertainty_of_d(us, big_u, up[idx], big_up[idx], corr)
    z = d / sigma[idx]
    z_prime = d / np.sqrt(sigma**2 + up**2)[idx]
    use_zp = np.isfinite(sigma) & (up > NEGLIGIBLE_FRACTION * sigma)
    performance = np.where(use_zp[idx], z_prime, z)
    d_flag = np.where(np.abs(d) < de[idx], FLAG_SATISFACTORY, FLAG_ACTION)
    zeta = d / u_d
    en = d / big_d
    return Scores(
        d=d,
        d_percent=np.where(rel[idx], 100.0 * d / np.where(rel, xp, 1.0)[idx], np.nan),
        z=z,
        z_prime=z_prime,
        zeta=zeta,
        en=en,
        u_d=u_d,
        U_d=big_d,
        performance=performance,
        d_flag=np.where(np.isnan(de[idx]), FLAG_NOT_SCORED, d_flag).astype(np.int8),
        z_flag=flag_z(z),
        z_prime_flag=flag_z(z_prime),
        zeta_flag=flag_z(zeta),
        en_flag=flag_en(en, en_limit),
        performance_flag=flag_z(performance),
        use_z_prime=use_zp,
        correlation_applied=applied,
        correlation_failed=failed,
    )


def _contributes(contributes: ArrayLike | None, n: int) -> BoolArray:
    if contributes is None:
        return np.zeros(n, dtype=np.bool_)
    c = np.asarray(contributes)
    if c.dtype != np.bool_ or c.shape != (n,):
        raise CoreInputError(f"contributes must be a boolean array of {n} entries, got {c.shape}")
    return c


def _rounds(z: ArrayLike) -> tuple[FloatArray, NDArray[np.intp]]:
    """Validate a (participants × rounds) z matrix with NaN for missed rounds."""
    zm = np.asarray(z, dtype=np.float64)
    if zm.ndim == 1:
        zm = zm[np.newaxis, :]
    if zm.ndim != 2:
        raise CoreInputError("z must be 2-D: one row per participant, one column per round")
    if np.isinf(zm).any():
        p, r = np.argwhere(np.isinf(zm))[0]
        raise CoreInputError(f"z of participant row {p}, round {r} is infinite")
    n = np.sum(~np.isnan(zm), axis=1)
    if (n == 0).any():
        p = int(np.flatnonzero(n == 0)[0])
        raise CoreInputError(f"participant row {p} has no z score in any round")
    return zm, n.astype(np.intp)


def rsz(z: ArrayLike) -> CombinedScore:
    """Rescaled sum of z-scores RSZ = Σz/√n (ISO 13528:2005 10.3; domain spec §4).

    ``z``: participants × rounds, NaN for a missed round (n counts the rest);
    1-D input is one participant.  Flags as for z (2 and 3).
    """
    zm, n = _rounds(z)
    value = np.nansum(zm, axis=1) / np.sqrt(n)
    return CombinedScore(value=value, n_rounds=n, flag=flag_z(value))


def rlp(z: ArrayLike, limit: float = 1.5) -> CombinedScore:
    """Relative laboratory performance RLP = √(Σz²/n) (domain spec §4).

    Same layout as :func:`rsz`.  RLP ≤ ``limit`` satisfactory, above it action.
    """
    zm, n = _rounds(z)
    value = np.sqrt(np.nansum(zm**2, axis=1) / n)
    flag = np.where(value <= limit, FLAG_SATISFACTORY, FLAG_ACTION).astype(np.int8)
    return CombinedScore(value=value, n_rounds=n, flag=flag)
