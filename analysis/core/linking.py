"""Linking several kits and loops to one reference by generalised least squares
(docs/domain.md §14; the classic description is Nielsen's least-squares evaluation of
intercomparisons).

At one measurement point every observation o is one laboratory's result on one kit:

    y_o = K_kit(o) + b_lab(o) + e_o,   e_o ~ N(0, u_o²), independent,

with K_k the value of kit k's device and b_j laboratory j's bias.  The pilot (or any
laboratory) may measure several kits, several times: each observation is a row.  The
model fixes differences only, so one linear constraint names the reference:

* ``"pilot"``: b_pilot = 0 — degrees of equivalence against the pilot (a reference
  laboratory's assigned value, per kit, linked through the pilot's measurements);
* ``"weighted_mean"``: Σ_j w_j b_j = 0 over the laboratories, w_j = 1/u_j² with u_j the
  root mean square of laboratory j's u — a consensus reference across every loop.  A
  series that is not a laboratory's result (the pilot's repeat measurements of the kits,
  a transfer series with its own free offset) is left out of the mean by ``in_mean``.

θ = (K, b) minimises Σ (y − Aθ)²/u² under Cθ = 0; it and its covariance come from the
bordered (KKT) system [[AᵀWA, Cᵀ], [C, 0]]: the top-left block of its inverse is cov(θ).
The degrees of equivalence d_j = b_j carry their full covariance (two laboratories of one
loop share the uncertainty of their kit's value); ``u_link`` is the part of u(d_j) that is
not the laboratory's own, √(u²(d_j) − u_j²/m_j) with m_j its number of observations.

A laboratory must be connected to the reference through kits (the graph of laboratories
and kits joined by observations must be connected); otherwise the system is singular and
the unconnected laboratories are named.

The covariance of the degrees of equivalence is also given *factored*, exactly:
cov(d) = diag(own) + F·Z·Fᵀ, with ``own`` each laboratory's own part 1/Σ(1/u²) and F (one
row per laboratory) and Z (r × r, r = kits + 1) from the Schur complement of the bordered
system on its laboratory block (which is diagonal, each observation having one
laboratory).  The off-diagonal covariances — and u_link² on the diagonal — are the F·Z·Fᵀ
part: n·(r + 1) + r² numbers instead of n(n + 1)/2, what a run stores
(docs/domain.md §14).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from analysis.core.groups import CoreInputError, FloatArray, IntArray

PILOT = "pilot"
WEIGHTED_MEAN = "weighted_mean"


@dataclass(frozen=True)
class Linked:
    """Kit values K (one per kit) and degrees of equivalence d = b (one per laboratory)
    against the reference, with the covariance of d and the link uncertainties; χ² of the
    fit and its degrees of freedom (observations − parameters + 1 constraint): with one
    bias per laboratory, χ² tests only the repeated measurements of the loop structure
    (the pilot's repeats, the linking laboratories); whether the laboratories agree with
    the reference is what their DoEs and En say.  ``doe_own``, ``doe_factor`` and
    ``doe_core`` give ``doe_covariance`` factored (:func:`factored_covariance`; the
    pilot's row of the factor and its own part are 0 under the pilot reference)."""

    kit_value: FloatArray
    u_kit_value: FloatArray
    doe: FloatArray
    doe_covariance: FloatArray
    u_link: FloatArray
    chi2: float
    dof: int
    doe_own: FloatArray
    doe_factor: FloatArray
    doe_core: FloatArray

    @property
    def u_doe(self) -> FloatArray:
        return np.sqrt(np.diag(self.doe_covariance))

    @property
    def doe_correlation(self) -> FloatArray:
        s = self.u_doe
        with np.errstate(invalid="ignore", divide="ignore"):
            return self.doe_covariance / np.outer(s, s)


def factored_covariance(own: ArrayLike, factor: ArrayLike, core: ArrayLike) -> FloatArray:
    """diag(own) + F·Z·Fᵀ: the covariance of degrees of equivalence from its factored form
    (:class:`Linked`; a subset of laboratories is the subset of the rows of ``own`` and
    ``factor``)."""
    d = np.asarray(own, dtype=np.float64)
    f = np.asarray(factor, dtype=np.float64).reshape(d.size, -1)
    z = np.asarray(core, dtype=np.float64).reshape(f.shape[1], f.shape[1])
    cov: FloatArray = f @ z @ f.T
    cov[np.diag_indices(d.size)] += d
    return cov


def _factors(
    w: FloatArray, kit: IntArray, lab: IntArray, n_kits: int, n_labs: int,
    constraint: FloatArray,
) -> tuple[FloatArray, FloatArray, FloatArray]:  # fmt: skip
    """The covariance of the biases factored (:class:`Linked`): with the bordered matrix
    ordered (b, K, λ) as [[D, E], [Eᵀ, H]], D diagonal, its inverse's b block is
    D⁻¹ + G·S⁻¹·Gᵀ, G = D⁻¹E, S = H − EᵀD⁻¹E (block inversion)."""
    own = np.bincount(lab, weights=w, minlength=n_labs)
    e = np.zeros((n_labs, n_kits + 1))
    np.add.at(e, (lab, kit), w)  # Σ w of laboratory j's observations on kit k
    e[:, n_kits] = constraint[n_kits:]
    h = np.zeros((n_kits + 1, n_kits + 1))
    h[np.arange(n_kits), np.arange(n_kits)] = np.bincount(kit, weights=w, minlength=n_kits)
    g = e / own[:, None]
    core = np.linalg.inv(h - e.T @ g)
    return 1.0 / own, g, 0.5 * (core + core.T)


def lab_components(kit: ArrayLike, lab: ArrayLike) -> IntArray:
    """Per laboratory (0 … max(lab)), a label of its connected component in the graph of
    laboratories and kits joined by observations: two laboratories share a label when
    some chain of kits and laboratories links them."""
    kk, jj = (np.asarray(a, dtype=np.intp) for a in (kit, lab))
    if not kk.size:
        return np.zeros(0, dtype=np.intp)
    return _components(int(kk.max()) + 1, int(jj.max()) + 1, kk, jj)


def _components(n_kits: int, n_labs: int, kit: IntArray, lab: IntArray) -> IntArray:
    """Connected component of every laboratory in the lab–kit graph (union-find)."""
    parent = np.arange(n_kits + n_labs)

    def find(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = int(parent[i])
        return i

    for k, j in zip(kit.tolist(), lab.tolist(), strict=True):
        a, b = find(k), find(n_kits + j)
        if a != b:
            parent[a] = b
    return np.array([find(n_kits + j) for j in range(n_labs)], dtype=np.intp)


def link(
    y: ArrayLike,
    u: ArrayLike,
    kit: ArrayLike,
    lab: ArrayLike,
    *,
    reference: str = PILOT,
    pilot: int = 0,
    in_mean: ArrayLike | None = None,
) -> Linked:
    """Degrees of equivalence of every laboratory against one reference across kits and
    loops, at one measurement point (see the module docstring).

    ``y``, ``u``: each observation's value and standard uncertainty; ``kit``, ``lab``: its
    kit and laboratory index (0-based; every index up to the largest is used);
    ``reference``: ``"pilot"`` (laboratory ``pilot`` has d = 0) or ``"weighted_mean"``;
    ``in_mean``: per laboratory, whether it enters the weighted-mean reference (default:
    all)."""
    yy, uu = (np.asarray(a, dtype=np.float64) for a in (y, u))
    kk, jj = (np.asarray(a, dtype=np.intp) for a in (kit, lab))
    if not (yy.shape == uu.shape == kk.shape == jj.shape) or yy.ndim != 1 or not yy.size:
        raise CoreInputError("one value, u, kit and laboratory per observation are needed")
    if not (np.isfinite(yy).all() and np.isfinite(uu).all() and (uu > 0).all()):
        raise CoreInputError("values must be finite and uncertainties finite and > 0")
    if kk.min() < 0 or jj.min() < 0:
        raise CoreInputError("kit and laboratory indexes must be >= 0")
    n_kits, n_labs = int(kk.max()) + 1, int(jj.max()) + 1
    for name, idx, n in (("kit", kk, n_kits), ("laboratory", jj, n_labs)):
        missing = np.setdiff1d(np.arange(n), idx)
        if missing.size:
            raise CoreInputError(f"{name} {int(missing[0])} has no observation")
    comp = _components(n_kits, n_labs, kk, jj)
    mean = np.ones(n_labs, dtype=bool) if in_mean is None else np.asarray(in_mean, dtype=bool)
    if mean.shape != (n_labs,) or not mean.any():
        raise CoreInputError("in_mean needs one flag per laboratory, at least one set")
    if reference == PILOT:
        if not 0 <= pilot < n_labs:
            raise CoreInputError(f"the pilot {pilot} is not one of the laboratories")
        apart = np.flatnonzero(comp != comp[pilot])
    elif reference == WEIGHTED_MEAN:
        apart = np.flatnonzero(comp != comp[int(np.flatnonzero(mean)[0])])
    else:
        raise CoreInputError(f"unknown reference {reference!r} (pilot or weighted_mean)")
    if apart.size:
        raise CoreInputError(
            f"laboratories {apart.tolist()[:10]} are not linked to the reference by any kit"
        )

    m = n_kits + n_labs
    a = np.zeros((yy.size, m))
    rows = np.arange(yy.size)
    a[rows, kk] = 1.0
    a[rows, n_kits + jj] = 1.0
    w = 1.0 / uu**2
    constraint = np.zeros(m)
    if reference == PILOT:
        constraint[n_kits + pilot] = 1.0
    else:
        u_rms = np.sqrt(np.bincount(jj, weights=uu**2) / np.bincount(jj))
        constraint[n_kits:] = np.where(mean, 1.0 / u_rms**2, 0.0)
    kkt = np.zeros((m + 1, m + 1))
    kkt[:m, :m] = a.T @ (w[:, None] * a)
    kkt[:m, m] = kkt[m, :m] = constraint
    rhs = np.concatenate([a.T @ (w * yy), [0.0]])
    inverse = np.linalg.inv(kkt)
    theta = inverse[:m, :] @ rhs
    cov = inverse[:m, :m]
    residual = yy - a @ theta
    own = np.bincount(jj, weights=w)  # Σ 1/u² of each laboratory's own observations
    cov_b: FloatArray = np.asarray(cov[n_kits:, n_kits:], dtype=np.float64).copy()
    with np.errstate(invalid="ignore"):
        u_link = np.sqrt(np.maximum(np.diag(cov_b) - 1.0 / own, 0.0))
    doe = theta[n_kits:].copy()
    own_part, factor, core = _factors(w, kk, jj, n_kits, n_labs, constraint)
    if reference == PILOT:  # zero by the constraint; written exactly, not as 1e-13
        doe[pilot] = 0.0
        cov_b[pilot, :] = cov_b[:, pilot] = 0.0
        u_link[pilot] = 0.0
        own_part[pilot] = 0.0
        factor[pilot, :] = 0.0
    return Linked(
        kit_value=theta[:n_kits], u_kit_value=np.sqrt(np.diag(cov)[:n_kits]),
        doe=doe, doe_covariance=cov_b, u_link=u_link,
        chi2=float(np.sum(w * residual**2)), dof=int(yy.size - m + 1),
        doe_own=own_part, doe_factor=factor, doe_core=core,
    )  # fmt: skip
