"""A linking laboratory in the analysis run (docs/domain.md §14): its measurement of its
other kit enters the link with its own bias, so it alone links a loop the pilot never
measured — exactly a dense weighted least-squares solve of the same observations (the
pilot's bias substituted by its constraint, 0) and the chain of differences by hand; the
run's notes say what it did; a measurement it cannot use is noted and ignored."""

from __future__ import annotations

import datetime as dt

import numpy as np
import pytest

from analysis.models import KitPointFit, KitScore
from labs.kits import kit_measurements_replace
from labs.models import KitMeasurement, Result
from tests.analysis.kit_rounds import START, add_kit, make_round, pilot_series, started

pytestmark = pytest.mark.django_db

CODES = [f"L{i}" for i in range(7)]
#: L3's measurement of Kit B: its date, value and U (k = 2), per point
LINK_DAY = START + dt.timedelta(days=40)
LINK_U = 3.0


@pytest.fixture
def run_of(django_capture_on_commit_callbacks):
    return lambda comparison: started(comparison, django_capture_on_commit_callbacks)


def _round(*, measured: bool = True) -> dict:
    """Kit A: the pilot L0 (with its repeats), L1, L2, L3; Kit B: L4, L5, L6, then L3 (its
    second slot, after its turn with Kit A), and no repeat of the pilot's at all."""
    r = make_round()
    labs = r["labs"]
    r["kit_a"] = add_kit(r, "Kit A", labs[:3])
    r["kit_b"] = add_kit(r, "Kit B", [*labs[3:], labs[2]], offset=0.6, repeats=False)
    if measured:
        lines = ["device,axis,frequency_hz,bench,direction,measured_on,sensitivity,"
                 "expanded_uncertainty,lab"]  # fmt: skip
        for i, p in enumerate(r["points"]):
            lines.append(f"MEMS 1,X,{p.frequency_hz:g},linear,vertical,{LINK_DAY},"
                         f"{419.7 + 0.3 * i},{LINK_U},L3")  # fmt: skip
        assert kit_measurements_replace(kit=r["kit_b"], text="\n".join(lines)) == 2
    return r


def _observations(r: dict, point) -> tuple[dict, list[tuple[str, int, float, float]]]:
    """Every observation rebuilt from the rows: (laboratory, kit, y, u); the transfer
    series of the pilot's repeats is laboratory "T"."""
    found = Result.objects.filter(measurement_point=point).select_related("submission__participant")
    res = {x.submission.participant.code: x for x in found}
    obs = [(c, 0 if c in ("L0", "L1", "L2", "L3") else 1, res[c].value,
            res[c].expanded_uncertainty / 2) for c in CODES]  # fmt: skip
    linking = KitMeasurement.objects.filter(measurement_point=point, participant__isnull=False)
    for code, value, big_u, k in linking.values_list(
        "participant__code", "value", "expanded_uncertainty", "coverage_factor"
    ):
        obs.append((code, 1, value, big_u / k))
    _, y, u = pilot_series(r["kit_a"], point)
    obs += [("T", 0, yi, ui) for yi, ui in zip(y, u, strict=True)]
    return res, obs


def _dense(obs: list[tuple[str, int, float, float]]) -> tuple[dict, np.ndarray, np.ndarray]:
    """Unknowns K_A, K_B, b_L1 … b_L6, b_T; b_L0 = 0 substituted (its column dropped)."""
    names = ["K_A", "K_B", *CODES[1:], "T"]
    a = np.zeros((len(obs), len(names)))
    for n, (lab, kit, _, _) in enumerate(obs):
        a[n, kit] = 1.0
        if lab != "L0":
            a[n, names.index(lab)] = 1.0
    y = np.array([o[2] for o in obs])
    w = 1 / np.array([o[3] for o in obs])
    theta, *_ = np.linalg.lstsq(a * w[:, None], y * w, rcond=None)
    cov = np.linalg.inv((a * w[:, None]).T @ (a * w[:, None]))
    chi2 = float(np.sum(((y - a @ theta) * w) ** 2))
    return {n: i for i, n in enumerate(names)}, theta, np.append(cov.diagonal(), chi2)


def test_a_loop_without_pilot_repeats_is_linked_through_a_lab_as_a_dense_solve(run_of):
    r = _round()
    run = run_of(r["comparison"])
    for point in r["points"]:
        fit = KitPointFit.objects.get(run=run, measurement_point=point)
        assert fit.reference == "pilot" and fit.unlinked == []
        res, obs = _observations(r, point)
        at, theta, extra = _dense(obs)
        var, chi2 = extra[:-1], extra[-1]
        assert [k["value"] for k in fit.kit_values] == pytest.approx(theta[:2].tolist(), rel=1e-10)
        assert [k["u"] for k in fit.kit_values] == pytest.approx(np.sqrt(var[:2]), rel=1e-9)
        assert fit.chi2 == pytest.approx(chi2, rel=1e-9, abs=1e-12)
        assert fit.dof == len(obs) - len(theta)  # 12 − 9: the pilot's four repeats fix one level
        for code in CODES[1:]:
            ks = KitScore.objects.get(run=run, result=res[code])
            j = at[code]
            own = sum(1 / o[3] ** 2 for o in obs if o[0] == code)
            assert ks.linked_d == pytest.approx(theta[j], abs=1e-8)
            assert ks.linked_u == pytest.approx(np.sqrt(var[j]), rel=1e-9)
            assert ks.u_link == pytest.approx(np.sqrt(var[j] - 1 / own), rel=1e-6)
        pilot = KitScore.objects.get(run=run, result=res["L0"])
        assert (pilot.linked_d, pilot.linked_u) == (0.0, 0.0)


def test_the_chain_by_hand_and_the_note_that_the_lab_links_the_kits(run_of):
    """Kit B's level comes only through L3: K_A = y_L0 (the pilot's repeats, one kit's,
    fix no level), b_L3 = y_L3,A − y_L0, K_B = y_L3,B − b_L3, so a laboratory of Kit B has
    d = y − y_L3,B + y_L3,A − y_L0 with u² the sum of the four u²."""
    r = _round()
    run = run_of(r["comparison"])
    point = r["points"][0]
    res, obs = _observations(r, point)
    y = {c: (res[c].value, res[c].expanded_uncertainty / 2) for c in CODES}
    link = next(o for o in obs if o[0] == "L3" and o[1] == 1)
    for code in ("L4", "L5", "L6"):
        ks = KitScore.objects.get(run=run, result=res[code])
        d = y[code][0] - link[2] + y["L3"][0] - y["L0"][0]
        u = np.sqrt(y[code][1] ** 2 + link[3] ** 2 + y["L3"][1] ** 2 + y["L0"][1] ** 2)
        assert ks.linked_d == pytest.approx(d, abs=1e-8)
        assert ks.linked_u == pytest.approx(u, rel=1e-9)
        assert ks.kit_id == r["kit_b"].pk
    l3 = KitScore.objects.get(run=run, result=res["L3"])
    assert l3.kit_id == r["kit_a"].pk  # its result: on the kit of its first slot
    assert l3.linked_d == pytest.approx(y["L3"][0] - y["L0"][0], abs=1e-8)
    assert l3.linked_u == pytest.approx(np.hypot(y["L3"][1], y["L0"][1]), rel=1e-9)
    fit = KitPointFit.objects.get(run=run, measurement_point=point)
    assert ("L3 holds slots on two kits: its result is taken on Kit A, its first slot, and "
            "its measurement of Kit B links the kits") in fit.notes  # fmt: skip
    assert not any("ignored" in n or "not linked" in n for n in fit.notes)


def test_without_the_labs_measurement_the_loop_is_named_and_the_note_warns(run_of):
    r = _round(measured=False)
    run = run_of(r["comparison"])
    fit = KitPointFit.objects.get(run=run, measurement_point=r["points"][0])
    assert fit.unlinked == ["L4", "L5", "L6"]
    assert ("L3 holds slots on two kits: its result is taken on Kit A, its first slot (the "
            "results table has no kit column); its measurement of Kit B here, stored with "
            "that kit's measurements under lab L3, would link the kits") in fit.notes  # fmt: skip
    assert "not linked to the reference by any kit: L4, L5, L6" in fit.notes
    on_b = KitScore.objects.filter(run=run, result__measurement_point=r["points"][0],
                                   kit=r["kit_b"])  # fmt: skip
    assert on_b.count() == 3 and set(on_b.values_list("linked_d", flat=True)) == {None}


def test_a_measurement_the_run_cannot_use_is_noted_and_ignored(run_of):
    """L3 has no result at 10 Hz: its measurement there links nothing; L4's of Kit B, the
    kit its own result is on, is no link either: both are named and change no number."""
    r = _round()
    ten = r["points"][1]
    Result.objects.filter(measurement_point=ten, submission__participant__code="L3").delete()
    clean = run_of(r["comparison"])
    l4 = r["labs"][3]
    KitMeasurement.objects.create(kit=r["kit_b"], measurement_point=r["points"][0],
                                  participant=l4, measured_on=LINK_DAY, value=425.0,
                                  expanded_uncertainty=LINK_U)  # fmt: skip
    run = run_of(r["comparison"])
    at_ten = KitPointFit.objects.get(run=run, measurement_point=ten)
    assert "L3's measurement of Kit B is ignored: it has no result on a kit here" in at_ten.notes
    assert at_ten.unlinked == ["L4", "L5", "L6"]
    at_five = KitPointFit.objects.get(run=run, measurement_point=r["points"][0])
    assert "L4's measurement of Kit B is ignored: its result is on that kit" in at_five.notes

    def rows(of):
        return sorted(KitScore.objects.filter(run=of).values_list(
            "result_id", "linked_d", "linked_u", "u_link"))  # fmt: skip

    assert rows(run) == rows(clean)
