"""A phase point in a kit round (docs/domain.md §12, §14): its observations are laid on a
line about their circular mean, drift-fitted and linked there and wrapped back, so phases
on either side of ±180° give the degrees of equivalence of the same phases turned by
−170° (and the differences by hand); a drift crossing 180° is numpy.polyfit's on the
unwrapped phases; where the phases spread over more than 90° the point is not linked."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.core.phase import wrap
from analysis.models import KitPointFit, KitScore, Score
from labs.models import KitMeasurement, KitSlot, Result
from tests.analysis.kit_rounds import add_kit, day_of, make_round, pilot_series, started

pytestmark = pytest.mark.django_db

#: each laboratory's phase on the line (L0 the pilot; L4–L6 on Kit B, about 1° above)
PHASES = {"L0": 179.2, "L1": 178.6, "L2": 179.9, "L3": 180.7,
          "L4": 181.1, "L5": 180.3, "L6": 181.6}  # fmt: skip
U = {"L0": 0.4, "L1": 0.8, "L2": 1.0, "L3": 0.6, "L4": 0.9, "L5": 0.7, "L6": 1.2}
#: the pilot's repeats of each kit on the line, with a wobble far inside their u
REPEATS = {"Kit A": 179.5, "Kit B": 180.6}
WOBBLE = (0.01, -0.012, 0.008, -0.006)


@pytest.fixture
def run_of(django_capture_on_commit_callbacks):
    return lambda comparison: started(comparison, django_capture_on_commit_callbacks)


def _phase_round(turn: float, *, repeats: dict | None = None, drift: float = 0.0) -> dict:
    """Two kits (Kit A: L1–L3, Kit B: L4–L6) whose 10 Hz point is a phase, every phase
    stored wrapped after a turn by ``turn`` degrees; Kit A's repeats drift by ``drift``
    per day."""
    r = make_round()
    phase = r["points"][1]
    phase.quantity = "phase"
    phase.save(update_fields=["quantity"])
    for code, value in PHASES.items():
        Result.objects.filter(measurement_point=phase, submission__participant__code=code).update(
            value=float(wrap(value + turn)), expanded_uncertainty=U[code]
        )
    r["kits"] = [add_kit(r, "Kit A", r["labs"][:3]), add_kit(r, "Kit B", r["labs"][3:])]
    for kit in r["kits"]:
        rows = KitMeasurement.objects.filter(kit=kit, measurement_point=phase).order_by(
            "measured_on"
        )
        for n, (m, w) in enumerate(zip(rows, WOBBLE, strict=True)):
            slope = drift if kit.name == "Kit A" else 0.0
            m.value = float(wrap((repeats or REPEATS)[kit.name] + w + slope * 40 * n + turn))
            m.save(update_fields=["value"])
    r["phase"] = phase
    return r


def _linked(run, phase) -> dict[str, tuple[float | None, float | None, float | None]]:
    rows = KitScore.objects.filter(run=run, result__measurement_point=phase).values_list(
        "result__submission__participant__code", "linked_d", "linked_u", "u_link"
    )
    return {code: (d, u, ul) for code, d, u, ul in rows}


def test_phases_across_180_link_as_the_same_phases_turned_by_minus_170(run_of):
    near = _phase_round(0.0)
    turned = _phase_round(-170.0)
    a, b = (run_of(r["comparison"]) for r in (near, turned))
    here, there = _linked(a, near["phase"]), _linked(b, turned["phase"])
    assert set(here) == set(PHASES) and all(v[0] is not None for v in here.values())
    for code in PHASES:
        assert here[code] == pytest.approx(there[code], abs=1e-9)
    fits = [KitPointFit.objects.get(run=run, measurement_point=r["phase"])
            for run, r in ((a, near), (b, turned))]  # fmt: skip
    assert fits[0].chi2 == pytest.approx(fits[1].chi2, rel=1e-6)
    for k0, k1 in zip(fits[0].kit_values, fits[1].kit_values, strict=True):
        assert -180 < k0["value"] <= 180 and -180 < k1["value"] <= 180
        assert float(wrap(k1["value"] - (k0["value"] - 170.0))) == pytest.approx(0.0, abs=1e-9)
    assert not any("spread" in n for n in fits[0].notes)


def test_phases_across_180_against_the_differences_by_hand(run_of):
    """The pilot reference: K_A = y_L0; K_B − K_A = the difference of the means of the
    pilot's repeats (equal u), so on Kit A d = y − y_L0 and on Kit B d = y − y_L0 − (m_B
    − m_A), each wrapped; u²(d) = u² + u²_L0 (+ the two means' u² on Kit B)."""
    r = _phase_round(0.0)
    run = run_of(r["comparison"])
    linked = _linked(run, r["phase"])
    means = {k.name: pilot_series(k, r["phase"]) for k in r["kits"]}
    m = {name: float(np.mean(np.unwrap(y, period=360))) for name, (_, y, _) in means.items()}
    u_mean = {name: float(np.sqrt(np.sum(u**2)) / u.size) for name, (_, _, u) in means.items()}
    stored = dict(Result.objects.filter(measurement_point=r["phase"]).values_list(
        "submission__participant__code", "value"))  # fmt: skip
    assert stored["L4"] < -178 and stored["L0"] > 179  # stored wrapped, on either side
    for code in PHASES:
        u0 = np.hypot(U[code] / 2, U["L0"] / 2) if code != "L0" else 0.0
        hop = 0.0
        if code in ("L4", "L5", "L6"):
            hop = m["Kit B"] - m["Kit A"]
            u0 = np.sqrt(u0**2 + u_mean["Kit A"] ** 2 + u_mean["Kit B"] ** 2)
        d = float(wrap(stored[code] - stored["L0"] - hop))
        assert linked[code][0] == pytest.approx(d, abs=1e-9)
        assert linked[code][1] == pytest.approx(u0, rel=1e-9)
    assert linked["L5"][0] == pytest.approx(180.3 - 179.2 - 1.1, abs=1e-9)


def test_a_phase_drift_crossing_180_is_polyfits_on_the_unwrapped_phases(run_of):
    """Kit A's phase drifts by 0.02°/day from 179.5°, past 180° (stored as −179.x)."""
    r = _phase_round(0.0, repeats={"Kit A": 179.5, "Kit B": 180.6}, drift=0.02)
    run = run_of(r["comparison"])
    kit_a = r["kits"][0]
    t, y, _ = pilot_series(kit_a, r["phase"])
    assert (y > 179).any() and (y < -179).any()  # the series crosses ±180° as stored
    on_line = np.unwrap(y, period=360)
    slope, at_mean = np.polyfit(t - t.mean(), on_line, 1)
    fit = KitPointFit.objects.get(run=run, measurement_point=r["phase"])
    drift = {d["kit"]: d for d in fit.drift}
    assert drift["Kit A"]["model"] == "linear" and drift["Kit B"]["model"] == "constant"
    assert drift["Kit A"]["slope"] == pytest.approx(slope, rel=1e-10)
    assert drift["Kit A"]["value"] == pytest.approx(float(wrap(at_mean)), abs=1e-9)
    stored = dict(Result.objects.filter(measurement_point=r["phase"]).values_list(
        "submission__participant__code", "value"))  # fmt: skip
    moved = {}
    for code in ("L0", "L1", "L2", "L3"):
        slot = KitSlot.objects.filter(kit=kit_a, participant__code=code).order_by("position")[0]
        dt_ = day_of(slot.starts_on, slot.ends_on) - t.mean()
        ks = KitScore.objects.get(run=run, result__measurement_point=r["phase"],
                                  result__submission__participant__code=code)  # fmt: skip
        assert ks.drift_correction == pytest.approx(-slope * dt_, rel=1e-9)
        moved[code] = stored[code] - slope * dt_
    for code in ("L1", "L2", "L3"):  # the reference laboratory's D, on the circle
        s = Score.objects.get(run=run, result__measurement_point=r["phase"],
                              result__submission__participant__code=code)  # fmt: skip
        assert s.d == pytest.approx(float(wrap(moved[code] - moved["L0"])), abs=1e-9)
        assert _linked(run, r["phase"])[code][0] == pytest.approx(s.d, abs=1e-9)


def test_phases_spread_over_more_than_90_degrees_are_not_linked(run_of):
    """Kit B's repeats at −60° beside results near 180°: the line would not hold the same
    angles, so the point is neither drift-fitted nor linked and says why."""
    r = _phase_round(0.0, repeats={"Kit A": 179.5, "Kit B": 300.0})
    run = run_of(r["comparison"])
    fit = KitPointFit.objects.get(run=run, measurement_point=r["phase"])
    assert fit.chi2 is None and fit.drift == [] and fit.reference == ""
    (said,) = [n for n in fit.notes if "spread" in n]
    assert said.startswith("its phases spread over 1")
    assert said.endswith("more than 90°: on a line they need not be the same angles, so the "
                         "point is not drift-corrected nor linked across kits; its scores are "
                         "against the round's assigned value")  # fmt: skip
    assert set(_linked(run, r["phase"]).values()) == {(None, None, None)}
    magnitude = KitPointFit.objects.get(run=run, measurement_point=r["points"][0])
    assert magnitude.reference == "pilot" and magnitude.chi2 is not None
