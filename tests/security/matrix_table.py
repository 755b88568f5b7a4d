"""The permission matrix's expectations: one row per route, statuses per persona.

A row gives one status per persona, in the order of ``tests.security.world.PERSONAS``:

    anonymous a_staff a_manager b_staff coord1 coord2 key_a key_a_revoked superuser

``a|b`` accepts either (a health probe may be down). URL kwargs are lab A's objects in
comparison 1; ``PK`` and ``TOKEN`` say which object a shared kwarg name means.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from tests.security.world import PERSONAS


@dataclass(frozen=True)
class Row:
    """Expected statuses for GET and POST, one per persona (see the module docstring)."""

    get: str
    post: str
    query: str = ""
    #: PUT, PATCH, DELETE where the view implements them
    other: dict[str, str] = field(default_factory=dict)

    def expected(self, method: str) -> dict[str, set[int]]:
        """Per persona, the status (or ``a|b``: either, for a health probe)."""
        line = {"GET": self.get, "POST": self.post}.get(method) or self.other[method]
        codes = line.split()
        assert len(codes) == len(PERSONAS), f"{self}: {len(codes)} statuses"
        return {
            p: {int(c) for c in code.split("|")} for p, code in zip(PERSONAS, codes, strict=True)
        }


#: ``pk`` names different objects in different routes: which of ``World.url_values``
PK = {
    "coordinator/<slug:code>/points/<int:pk>/": "point",
    "coordinator/<slug:code>/review/results/<int:pk>/check/": "result",
    "coordinator/<slug:code>/analysis/runs/<int:pk>/": "run",
    "coordinator/<slug:code>/analysis/runs/<int:pk>/progress/": "run",
    "api/v1/analysis-runs/<int:pk>/": "run",
    "api/v1/analysis-runs/<int:pk>/cancel/": "run",
    "coordinator/<slug:code>/analysis/runs/<int:pk>/cancel/": "run",
    # the world holds no raw record: any pk is someone else's (or nobody's) -> 404;
    # tests/labs/test_raw_data*.py check a real record persona by persona
    "lab/comparisons/<slug:code>/raw-data/<int:pk>/": "result",
    "api/v1/comparisons/<slug:code>/raw-data/<int:pk>/": "result",
    # the world holds no notice either: any pk is nobody's -> 404 for the signed-in;
    # tests/labs/test_notices.py checks a real notice persona by persona
    "lab/notices/<int:pk>/read/": "result",
    # nor a publication: tests/analysis/test_publication_jobs.py checks a real one
    "coordinator/<slug:code>/publication/<int:pk>/": "result",
    "coordinator/<slug:code>/publication/<int:pk>/progress/": "result",
    "api/v1/publications/<int:pk>/": "result",
    # the world holds no application either: any pk is nobody's -> 404 (or the coordinator
    # pages' 404 for the comparison first); tests/labs/test_enrolment.py checks real ones
    "lab/applications/<int:pk>/withdraw/": "result",
    "coordinator/<slug:code>/kits/<int:pk>/plan/": "result",
    "coordinator/<slug:code>/kits/<int:pk>/dispatch/": "result",
    "coordinator/<slug:code>/kits/<int:pk>/returned/": "result",
    "coordinator/<slug:code>/kits/<int:pk>/measurements/": "result",
    "lab/comparisons/<slug:code>/kit/<int:pk>/received/": "result",
    "lab/comparisons/<slug:code>/kit/<int:pk>/dispatched/": "result",
    "coordinator/<slug:code>/applications/<int:pk>/accept/": "result",
    "coordinator/<slug:code>/applications/<int:pk>/decline/": "result",
    "api/v1/comparisons/<slug:code>/applications/<int:pk>/accept/": "result",
    "api/v1/comparisons/<slug:code>/applications/<int:pk>/decline/": "result",
}
#: the password-reset link carries its own token (an invalid one here)
TOKEN = {"accounts/reset/<uidb64>/<token>/": "reset_token"}

#                  anon  aS   aM   bS   c1   c2   kA   kR   su
TABLE: dict[str, Row] = {
    # public probe: 200 (or 503 when the database or broker is down)
    "healthz": Row(
        get="200|503 200|503 200|503 200|503 200|503 200|503 200|503 200|503 200|503",
        post="405 405 405 405 405 405 405 405 405",
    ),
    # the API's root: where its documentation is, for everyone (a revoked key is refused)
    "api/v1/": Row(
        get="200 200 200 200 200 200 200 401 200",
        post="405 405 405 405 405 405 405 401 405",
    ),
    # landing page for everyone, a lab member's dashboard
    "": Row(
        get="200 200 200 200 200 200 200 200 200",
        post="405 405 405 405 405 405 405 405 405",
    ),
    # the dashboard lists only the user's own labs' participations (none for coordinators)
    "lab/": Row(
        get="302 200 200 200 200 200 302 302 200",
        post="302 405 405 405 405 405 302 302 405",
    ),
    "lab/comparisons/<slug:code>/": Row(
        get="302 200 200 200 404 404 302 302 404",
        post="302 405 405 405 405 405 302 302 405",
    ),
    "lab/comparisons/<slug:code>/results/": Row(
        get="302 200 200 200 404 404 302 302 404",
        post="302 200 200 200 404 404 302 302 404",
    ),
    "lab/comparisons/<slug:code>/upload/": Row(
        get="302 200 200 200 404 404 302 302 404",
        post="302 200 200 200 404 404 302 302 404",
    ),
    "lab/comparisons/<slug:code>/template.<str:fmt>": Row(
        get="302 200 200 200 404 404 302 302 404",
        post="302 405 405 405 405 405 302 302 405",
    ),
    "lab/comparisons/<slug:code>/submissions/": Row(
        get="302 200 200 200 404 404 302 302 404",
        post="302 405 405 405 405 405 302 302 405",
    ),
    # version 2 is lab A's alone: lab B has no version 2
    "lab/comparisons/<slug:code>/submissions/<int:version>/": Row(
        get="302 200 200 404 404 404 302 302 404",
        post="302 405 405 405 405 405 302 302 405",
    ),
    # the user's own laboratory's history (docs/domain.md §4.1): its members only; a person
    # of no laboratory (the coordinators, the superuser) has none: 404
    "lab/history/": Row(
        get="302 200 200 200 404 404 302 302 404",
        post="302 405 405 405 405 405 302 302 405",
    ),
    # the inbox's buttons: POST only; one notice of the user's own labs, else 404
    "lab/notices/<int:pk>/read/": Row(
        get="302 405 405 405 405 405 302 302 405",
        post="302 404 404 404 404 404 302 302 404",
    ),
    # every unread notice of the user's own labs (none for coordinators): back to /lab/
    "lab/notices/read/": Row(
        get="302 405 405 405 405 405 302 302 405",
        post="302 302 302 302 302 302 302 302 302",
    ),
    # the open calls, read by every signed-in person (a sentence says who may apply)
    "lab/calls/": Row(
        get="302 200 200 200 200 200 302 302 200",
        post="302 405 405 405 405 405 302 302 405",
    ),
    # lab managers only (404 for staff, coordinators and superusers, who manage no lab); C1
    # is visible to lab A, which takes part: the form says so and stores nothing
    "lab/calls/<slug:code>/apply/": Row(
        get="302 404 200 404 404 404 302 302 404",
        post="302 404 200 404 404 404 302 302 404",
    ),
    # an application of a lab the user manages, POST only; the world has none -> 404
    "lab/applications/<int:pk>/withdraw/": Row(
        get="302 405 405 405 405 405 302 302 405",
        post="302 404 404 404 404 404 302 302 404",
    ),
    # managers are redirected to their lab's key page
    "lab/api-keys/": Row(
        get="302 404 302 404 404 404 302 302 404",
        post="302 405 405 405 405 405 302 302 405",
    ),
    # lab A's managers only; staff and everyone else 404
    "lab/<int:lab_pk>/api-keys/": Row(
        get="302 404 200 404 404 404 302 302 404",
        post="302 404 200 404 404 404 302 302 404",
    ),
    "lab/<int:lab_pk>/api-keys/<str:prefix>/revoke/": Row(
        get="302 404 200 404 404 404 302 302 404",
        post="302 404 302 404 404 404 302 302 404",
    ),
    "coordinator/": Row(
        get="302 404 404 404 200 200 302 302 200",
        post="302 405 405 405 405 405 302 302 405",
    ),
    # needs proficiency.add_comparison (both coordinators have it)
    "coordinator/new/": Row(
        get="302 404 404 404 200 200 302 302 200",
        post="302 404 404 404 200 200 302 302 200",
    ),
    "coordinator/<slug:code>/": Row(
        get="302 404 404 404 200 404 302 302 200",
        post="302 405 405 405 405 405 302 302 405",
    ),
    "coordinator/<slug:code>/edit/": Row(
        get="302 404 404 404 200 404 302 302 200",
        post="302 404 404 404 200 404 302 302 200",
    ),
    "coordinator/<slug:code>/status/": Row(
        get="302 405 405 405 405 405 302 302 405",
        post="302 404 404 404 302 404 302 302 302",
    ),
    "coordinator/<slug:code>/report-notes/": Row(
        get="302 404 404 404 200 404 302 302 200",
        post="302 404 404 404 200 404 302 302 200",
    ),
    "coordinator/<slug:code>/devices/new/": Row(
        get="302 404 404 404 200 404 302 302 200",
        post="302 404 404 404 200 404 302 302 200",
    ),
    "coordinator/<slug:code>/points/generate/": Row(
        get="302 404 404 404 200 404 302 302 200",
        post="302 404 404 404 200 404 302 302 200",
    ),
    "coordinator/<slug:code>/points/<int:pk>/": Row(
        get="302 404 404 404 200 404 302 302 200",
        post="302 404 404 404 200 404 302 302 200",
    ),
    "coordinator/<slug:code>/participants/invite/": Row(
        get="302 404 404 404 200 404 302 302 200",
        post="302 404 404 404 200 404 302 302 200",
    ),
    "coordinator/<slug:code>/participants/<str:participant>/scope/": Row(
        get="302 404 404 404 200 404 302 302 200",
        post="302 404 404 404 200 404 302 302 200",
    ),
    "coordinator/<slug:code>/participants/<str:participant>/reference/": Row(
        get="302 405 405 405 405 405 302 302 405",
        post="302 404 404 404 302 404 302 302 302",
    ),
    # the round's coordinators; an application they do not have (none in the world) -> 404
    "coordinator/<slug:code>/applications/": Row(
        get="302 404 404 404 200 404 302 302 200",
        post="302 405 405 405 405 405 302 302 405",
    ),
    "coordinator/<slug:code>/applications/<int:pk>/accept/": Row(
        get="302 404 404 404 404 404 302 302 404",
        post="302 404 404 404 404 404 302 302 404",
    ),
    "coordinator/<slug:code>/applications/<int:pk>/decline/": Row(
        get="302 404 404 404 404 404 302 302 404",
        post="302 404 404 404 404 404 302 302 404",
    ),
    "coordinator/<slug:code>/review/": Row(
        get="302 404 404 404 200 404 302 302 200",
        post="302 405 405 405 405 405 302 302 405",
    ),
    # accept every complete submission: POST only, the round's coordinators (then back to the
    # review list); its confirmation page is confirm/<action>/
    "coordinator/<slug:code>/review/accept-complete/": Row(
        get="302 405 405 405 405 405 302 302 405",
        post="302 404 404 404 302 404 302 302 302",
    ),
    "coordinator/<slug:code>/review/<str:participant>/v<int:version>/": Row(
        get="302 404 404 404 200 404 302 302 200",
        post="302 404 404 404 200 404 302 302 200",
    ),
    "coordinator/<slug:code>/review/results/<int:pk>/check/": Row(
        get="302 405 405 405 405 405 302 302 405",
        post="302 404 404 404 302 404 302 302 302",
    ),
    "coordinator/<slug:code>/analysis/run/": Row(
        get="302 405 405 405 405 405 302 302 405",
        post="302 404 404 404 302 404 302 302 302",
    ),
    # what an action will do, and the report previews: the round's coordinators only
    "coordinator/<slug:code>/confirm/<slug:action>/": Row(
        get="302 404 404 404 200 404 302 302 200",
        post="302 405 405 405 405 405 302 302 405",
    ),
    "coordinator/<slug:code>/reports/preview/": Row(
        get="302 404 404 404 200 404 302 302 200",
        post="302 405 405 405 405 405 302 302 405",
    ),
    "coordinator/<slug:code>/reports/preview/<slug:which>.pdf": Row(
        get="302 404 404 404 200 404 302 302 200",
        post="302 405 405 405 405 405 302 302 405",
    ),
    # a new version of one report: POST only, the round's coordinators (then the reports page,
    # with the service's refusal as a message when the world's round has no run)
    "coordinator/<slug:code>/reports/reissue/": Row(
        get="302 405 405 405 405 405 302 302 405",
        post="302 404 404 404 302 404 302 302 302",
    ),
    "coordinator/<slug:code>/analysis/runs/": Row(
        get="302 404 404 404 200 404 302 302 200",
        post="302 405 405 405 405 405 302 302 405",
    ),
    "coordinator/<slug:code>/analysis/runs/<int:pk>/": Row(
        get="302 404 404 404 200 404 302 302 200",
        post="302 405 405 405 405 405 302 302 405",
    ),
    "coordinator/<slug:code>/analysis/runs/<int:pk>/progress/": Row(
        get="302 404 404 404 200 404 302 302 200",
        post="302 405 405 405 405 405 302 302 405",
    ),
    # the world's run has ended: its coordinator is sent back to the run page with a note
    "coordinator/<slug:code>/analysis/runs/<int:pk>/cancel/": Row(
        get="302 405 405 405 405 405 302 302 405",
        post="302 404 404 404 302 404 302 302 302",
    ),
    "coordinator/<slug:code>/publish/": Row(
        get="302 405 405 405 405 405 302 302 405",
        post="302 404 404 404 302 404 302 302 302",
    ),
    "coordinator/<slug:code>/publication/<int:pk>/": Row(
        get="302 404 404 404 404 404 302 302 404",
        post="302 405 405 405 405 405 302 302 405",
    ),
    "coordinator/<slug:code>/publication/<int:pk>/progress/": Row(
        get="302 404 404 404 404 404 302 302 404",
        post="302 405 405 405 405 405 302 302 405",
    ),
    "coordinator/<slug:code>/results/": Row(
        get="302 404 404 404 200 404 302 302 200",
        post="302 405 405 405 405 405 302 302 405",
    ),
    "coordinator/<slug:code>/scores/": Row(
        get="302 404 404 404 200 404 302 302 200",
        post="302 405 405 405 405 405 302 302 405",
    ),
    "coordinator/<slug:code>/performance/": Row(
        get="302 404 404 404 200 404 302 302 200",
        post="302 405 405 405 405 405 302 302 405",
    ),
    "coordinator/<slug:code>/performance/<slug:lab>/": Row(
        get="302 404 404 404 200 404 302 302 200",
        post="302 405 405 405 405 405 302 302 405",
    ),
    "coordinator/<slug:code>/scores.<str:fmt>": Row(
        get="302 404 404 404 200 404 302 302 200",
        post="302 405 405 405 405 405 302 302 405",
    ),
    "coordinator/<slug:code>/charts/": Row(
        get="302 404 404 404 200 404 302 302 200",
        post="302 405 405 405 405 405 302 302 405",
    ),
    "coordinator/<slug:code>/charts/<slug:chart>.<str:ext>": Row(
        get="302 404 404 404 200 404 302 302 200",
        post="302 405 405 405 405 405 302 302 405",
    ),
    "coordinator/<slug:code>/compatibility/": Row(
        get="302 404 404 404 200 404 302 302 200",
        post="302 405 405 405 405 405 302 302 405",
    ),
    "coordinator/<slug:code>/consistency/": Row(
        get="302 404 404 404 200 404 302 302 200",
        post="302 405 405 405 405 405 302 302 405",
    ),
    "coordinator/<slug:code>/consistency.csv": Row(
        get="302 404 404 404 200 404 302 302 200",
        post="302 405 405 405 405 405 302 302 405",
    ),
    # drift and linking of a kit round (docs/domain.md §13, §14): the coordinators' only
    "coordinator/<slug:code>/results/kits/": Row(
        get="302 404 404 404 200 404 302 302 200",
        post="302 405 405 405 405 405 302 302 405",
    ),
    # the covariance of the linked degrees of equivalence (docs/domain.md §14), as a CSV
    "coordinator/<slug:code>/results/kits/covariance.csv": Row(
        get="302 404 404 404 200 404 302 302 200",
        post="302 405 405 405 405 405 302 302 405",
    ),
    # the round's archive: asked for by the round's coordinators (POST; built inline, then
    # back to the results page), its status line and the ready ZIP (the world holds the
    # coordinators' archive of the run)
    "coordinator/<slug:code>/archive/": Row(
        get="302 405 405 405 405 405 302 302 405",
        post="302 404 404 404 302 404 302 302 302",
    ),
    "coordinator/<slug:code>/archive/status/": Row(
        get="302 404 404 404 200 404 302 302 200",
        post="302 405 405 405 405 405 302 302 405",
    ),
    "coordinator/<slug:code>/archive/run<int:run>.zip": Row(
        get="302 404 404 404 200 404 302 302 200",
        post="302 405 405 405 405 405 302 302 405",
    ),
    # participants' results pages: 404 until published (comparison 1 is analysed)
    "results/<slug:code>/": Row(
        get="302 404 404 404 404 404 302 302 404",
        post="302 405 405 405 405 405 302 302 405",
    ),
    "results/<slug:code>/scores/": Row(
        get="302 404 404 404 404 404 302 302 404",
        post="302 405 405 405 405 405 302 302 405",
    ),
    "results/<slug:code>/kits/": Row(
        get="302 404 404 404 404 404 302 302 404",
        post="302 405 405 405 405 405 302 302 405",
    ),
    "results/<slug:code>/scores.<str:fmt>": Row(
        get="302 404 404 404 404 404 302 302 404",
        post="302 405 405 405 405 405 302 302 405",
    ),
    "results/<slug:code>/charts/": Row(
        get="302 404 404 404 404 404 302 302 404",
        post="302 405 405 405 405 405 302 302 405",
    ),
    "results/<slug:code>/charts/<slug:chart>.<str:ext>": Row(
        get="302 404 404 404 404 404 302 302 404",
        post="302 405 405 405 405 405 302 302 405",
    ),
    "results/<slug:code>/compatibility/": Row(
        get="302 404 404 404 404 404 302 302 404",
        post="302 405 405 405 405 405 302 302 405",
    ),
    "results/<slug:code>/consistency/": Row(
        get="302 404 404 404 404 404 302 302 404",
        post="302 405 405 405 405 405 302 302 405",
    ),
    "results/<slug:code>/consistency.csv": Row(
        get="302 404 404 404 404 404 302 302 404",
        post="302 405 405 405 405 405 302 302 405",
    ),
    "results/<slug:code>/archive/": Row(
        get="302 405 405 405 405 405 302 302 405",
        post="302 404 404 404 404 404 302 302 404",
    ),
    "results/<slug:code>/archive/status/": Row(
        get="302 404 404 404 404 404 302 302 404",
        post="302 405 405 405 405 405 302 302 405",
    ),
    "results/<slug:code>/archive/run<int:run>.zip": Row(
        get="302 404 404 404 404 404 302 302 404",
        post="302 405 405 405 405 405 302 302 405",
    ),
    # participants see the page (no report before publication), coordinator 2 404
    "reports/<slug:code>/": Row(
        get="302 200 200 200 200 404 302 302 200",
        post="302 200 200 200 200 404 302 302 200",
    ),
    "accounts/login/": Row(
        get="200 200 200 200 200 200 200 200 200",
        post="200 200 200 200 200 200 200 200 200",
    ),
    "accounts/logout/": Row(
        get="405 405 405 405 405 405 405 405 405",
        post="302 302 302 302 302 302 302 302 302",
    ),
    "accounts/password_change/": Row(
        get="302 200 200 200 200 200 302 302 200",
        post="302 200 200 200 200 200 302 302 200",
    ),
    "accounts/password_change/done/": Row(
        get="302 200 200 200 200 200 302 302 200",
        post="302 405 405 405 405 405 302 302 405",
    ),
    "accounts/password_reset/": Row(
        get="200 200 200 200 200 200 200 200 200",
        post="200 200 200 200 200 200 200 200 200",
    ),
    "accounts/password_reset/done/": Row(
        get="200 200 200 200 200 200 200 200 200",
        post="405 405 405 405 405 405 405 405 405",
    ),
    "accounts/reset/<uidb64>/<token>/": Row(
        get="200 200 200 200 200 200 200 200 200",
        post="200 200 200 200 200 200 200 200 200",
    ),
    "accounts/reset/done/": Row(
        get="200 200 200 200 200 200 200 200 200",
        post="405 405 405 405 405 405 405 405 405",
    ),
    # the rounds taking applications, for every caller (none in the world)
    "api/v1/calls/": Row(
        get="401 200 200 200 200 200 200 401 200",
        post="401 405 405 405 405 405 405 401 405",
    ),
    # POST {}: 403 without add_comparison, 400 (empty body) with it
    "api/v1/comparisons/": Row(
        get="401 200 200 200 200 200 200 401 200",
        post="401 403 403 403 400 400 403 401 400",
    ),
    "api/v1/comparisons/<slug:code>/": Row(
        get="401 200 200 200 200 404 200 401 200",
        post="401 405 405 405 405 405 405 401 405",
    ),
    "api/v1/comparisons/<slug:code>/measurands/": Row(
        get="401 200 200 200 200 404 200 401 200",
        post="401 405 405 405 405 405 405 401 405",
    ),
    "api/v1/comparisons/<slug:code>/template.csv": Row(
        get="401 200 200 200 200 404 200 401 200",
        post="401 405 405 405 405 405 405 401 405",
    ),
    # POST {}: 400 for participants, 403 for coordinators (not participants)
    "api/v1/comparisons/<slug:code>/submissions/": Row(
        get="401 200 200 200 200 404 200 401 200",
        post="401 400 400 400 403 404 400 401 403",
    ),
    # POST JSON: 415 (multipart only) once the caller may submit
    "api/v1/comparisons/<slug:code>/submissions/upload/": Row(
        get="401 405 405 405 405 405 405 401 405",
        post="401 415 415 415 403 404 415 401 403",
    ),
    # coordinators must say ?participant= (400); lab B has no version 2
    "api/v1/comparisons/<slug:code>/submissions/<int:version>/": Row(
        get="401 200 200 404 400 404 200 401 400",
        post="401 405 405 405 405 405 405 401 405",
    ),
    # participants see the comparison but lack the role: 403
    "api/v1/comparisons/<slug:code>/analysis-runs/": Row(
        get="401 403 403 403 200 404 403 401 200",
        post="401 403 403 403 202 404 403 401 202",
    ),
    "api/v1/analysis-runs/<int:pk>/": Row(
        get="401 404 404 404 200 404 404 401 200",
        post="401 405 405 405 405 405 405 401 405",
    ),
    # the world's run has ended: 409 for its coordinators, 404 for everyone else
    "api/v1/analysis-runs/<int:pk>/cancel/": Row(
        get="401 405 405 405 405 405 405 401 405",
        post="401 404 404 404 409 404 404 401 409",
    ),
    # participants: 409 until published
    "api/v1/comparisons/<slug:code>/scores/": Row(
        get="401 409 409 409 200 404 409 401 200",
        post="401 405 405 405 405 405 405 401 405",
    ),
    # the covariance of the linked degrees of equivalence: coordinators only, every entry a
    # pair of laboratories (an empty list in a round without kits)
    "api/v1/comparisons/<slug:code>/doe-covariance/": Row(
        get="401 403 403 403 200 404 403 401 200",
        post="401 405 405 405 405 405 405 401 405",
    ),
    # coordinators: 400 without ?factor=
    "api/v1/comparisons/<slug:code>/compatibility/": Row(
        get="401 409 409 409 400 404 409 401 400",
        post="401 405 405 405 405 405 405 401 405",
    ),
    # 409: no authoriser for the final reports yet
    "api/v1/comparisons/<slug:code>/publish/": Row(
        get="401 405 405 405 405 405 405 401 405",
        post="401 403 403 403 409 404 403 401 409",
    ),
    "api/v1/publications/<int:pk>/": Row(
        get="401 404 404 404 404 404 404 401 404",
        post="401 405 405 405 405 405 405 401 405",
    ),
    "api/v1/comparisons/<slug:code>/transition/": Row(
        get="401 405 405 405 405 405 405 401 405",
        post="401 403 403 403 400 404 403 401 400",
    ),
    "api/v1/comparisons/<slug:code>/submissions/<str:participant>/<int:version>/decision/": Row(
        get="401 405 405 405 405 405 405 401 405",
        post="401 403 403 403 400 404 403 401 400",
    ),
    # nothing waiting in the world: 200 with an empty list
    "api/v1/comparisons/<slug:code>/submissions/accept-complete/": Row(
        get="401 405 405 405 405 405 405 401 405",
        post="401 403 403 403 200 404 403 401 200",
    ),
    "api/v1/comparisons/<slug:code>/check-requests/": Row(
        get="401 405 405 405 405 405 405 401 405",
        post="401 403 403 403 400 404 403 401 400",
    ),
    "api/v1/comparisons/<slug:code>/devices/": Row(
        get="401 405 405 405 405 405 405 401 405",
        post="401 403 403 403 400 404 403 401 400",
    ),
    "api/v1/comparisons/<slug:code>/measurands/generate/": Row(
        get="401 405 405 405 405 405 405 401 405",
        post="401 403 403 403 400 404 403 401 400",
    ),
    "api/v1/comparisons/<slug:code>/participants/": Row(
        get="401 405 405 405 405 405 405 401 405",
        post="401 403 403 403 400 404 403 401 400",
    ),
    "api/v1/comparisons/<slug:code>/participants/<str:participant>/scope/": Row(
        get="401 403 403 403 200 404 403 401 200",
        post="401 405 405 405 405 405 405 401 405",
        other={"PUT": "401 403 403 403 200 404 403 401 200"},
    ),
    "api/v1/comparisons/<slug:code>/reports/": Row(
        get="401 200 200 200 200 404 200 401 200",
        post="401 403 403 403 400 404 403 401 400",
    ),
    # lab A's preliminary report: participants only after publication
    "api/v1/reports/<str:token>/pdf": Row(
        get="401 404 404 404 200 404 404 401 200",
        post="401 405 405 405 405 405 405 401 405",
    ),
    "api/v1/comparisons/<slug:code>/report-notes/": Row(
        get="401 403 403 403 200 404 403 401 200",
        post="401 405 405 405 405 405 405 401 405",
        other={"PUT": "401 403 403 403 200 404 403 401 200"},
    ),
    # raw records: lab B takes part in comparison 1 too; POST {} is an
    # invalid form (200) for participants
    "lab/comparisons/<slug:code>/raw-data/": Row(
        get="302 200 200 200 404 404 302 302 404",
        post="302 200 200 200 404 404 302 302 404",
    ),
    "lab/comparisons/<slug:code>/raw-data/<int:pk>/": Row(
        get="302 404 404 404 404 404 302 302 404",
        post="302 405 405 405 405 405 302 302 405",
    ),
    "coordinator/<slug:code>/raw-data/": Row(
        get="302 404 404 404 200 404 302 302 200",
        post="302 405 405 405 405 405 302 302 405",
    ),
    # kits (docs/domain.md §15): the world holds no kit or slot, so any pk is nobody's ->
    # 404; tests/labs/test_kit_pages.py checks real ones persona by persona
    "coordinator/<slug:code>/kits/": Row(
        get="302 404 404 404 200 404 302 302 200",
        post="302 405 405 405 405 405 302 302 405",
    ),
    "coordinator/<slug:code>/kits/new/": Row(
        get="302 405 405 405 405 405 302 302 405",
        post="302 404 404 404 400 404 302 302 400",
    ),
    "coordinator/<slug:code>/kits/<int:pk>/plan/": Row(
        get="302 405 405 405 405 405 302 302 405",
        post="302 404 404 404 404 404 302 302 404",
    ),
    "coordinator/<slug:code>/kits/<int:pk>/dispatch/": Row(
        get="302 405 405 405 405 405 302 302 405",
        post="302 404 404 404 404 404 302 302 404",
    ),
    "coordinator/<slug:code>/kits/<int:pk>/measurements/": Row(
        get="302 405 405 405 405 405 302 302 405",
        post="302 404 404 404 404 404 302 302 404",
    ),
    "coordinator/<slug:code>/kits/<int:pk>/returned/": Row(
        get="302 405 405 405 405 405 302 302 405",
        post="302 404 404 404 404 404 302 302 404",
    ),
    "lab/comparisons/<slug:code>/kit/": Row(
        get="302 200 200 200 404 404 302 302 404",
        post="302 405 405 405 405 405 302 302 405",
    ),
    "lab/comparisons/<slug:code>/kit/<int:pk>/received/": Row(
        get="302 405 405 405 405 405 302 302 405",
        post="302 404 404 404 404 404 302 302 404",
    ),
    "lab/comparisons/<slug:code>/kit/<int:pk>/dispatched/": Row(
        get="302 405 405 405 405 405 302 302 405",
        post="302 404 404 404 404 404 302 302 404",
    ),
    # C1 takes no applications but is visible to its labs and coordinators: GET lists their
    # own (coordinators all); POST: 409 for lab A's manager and key (it takes part), 403 for
    # staff and for people who manage no laboratory; coord2 does not see C1 -> 404
    "api/v1/comparisons/<slug:code>/applications/": Row(
        get="401 200 200 200 200 404 200 401 200",
        post="401 403 409 403 403 404 409 401 403",
    ),
    # the world holds no application: 404 for everyone signed in
    "api/v1/comparisons/<slug:code>/applications/<int:pk>/accept/": Row(
        get="401 405 405 405 405 405 405 401 405",
        post="401 404 404 404 404 404 404 401 404",
    ),
    "api/v1/comparisons/<slug:code>/applications/<int:pk>/decline/": Row(
        get="401 405 405 405 405 405 405 401 405",
        post="401 404 404 404 404 404 404 401 404",
    ),
    # POST JSON: 415 (multipart only) once the caller may upload; coordinators 403
    "api/v1/comparisons/<slug:code>/raw-data/": Row(
        get="401 200 200 200 200 404 200 401 200",
        post="401 415 415 415 403 404 415 401 403",
    ),
    "api/v1/comparisons/<slug:code>/raw-data/<int:pk>/": Row(
        get="401 404 404 404 404 404 404 401 404",
        post="401 405 405 405 405 405 405 401 405",
    ),
    "api/schema/": Row(
        get="200 200 200 200 200 200 200 200 200",
        post="405 405 405 405 405 405 405 405 405",
    ),
    "api/docs/": Row(
        get="200 200 200 200 200 200 200 200 200",
        post="405 405 405 405 405 405 405 405 405",
    ),
}

#: Routes that may be absent (added by another change); their row is used when present.
OPTIONAL = {"healthz", "healthz/"}


#: After publication the participants read the results: lab B's pages then show every
#: participant's results by code (as the summary report does, docs/domain.md §9) but never a
#: laboratory's name, and nothing of lab A reaches coordinator 2 or a signed-out caller.
PUBLISHED: dict[str, Row] = {
    "results/<slug:code>/": Row(get="302 200 200 200 404 404 302 302 404", post=""),
    "results/<slug:code>/scores/": Row(get="302 200 200 200 404 404 302 302 404", post=""),
    "results/<slug:code>/kits/": Row(get="302 200 200 200 404 404 302 302 404", post=""),
    "results/<slug:code>/scores.<str:fmt>": Row(get="302 200 200 200 404 404 302 302 404", post=""),
    "results/<slug:code>/charts/": Row(get="302 200 200 200 404 404 302 302 404", post=""),
    "results/<slug:code>/charts/<slug:chart>.<str:ext>": Row(
        get="302 200 200 200 404 404 302 302 404", post=""
    ),
    "results/<slug:code>/compatibility/": Row(get="302 200 200 200 404 404 302 302 404", post=""),
    "results/<slug:code>/consistency/": Row(get="302 200 200 200 404 404 302 302 404", post=""),
    "results/<slug:code>/consistency.csv": Row(get="302 200 200 200 404 404 302 302 404", post=""),
    "results/<slug:code>/archive/status/": Row(get="302 200 200 200 404 404 302 302 404", post=""),
    # each participant reads its own archive only: lab A's is built, lab B has none (404)
    "results/<slug:code>/archive/run<int:run>.zip": Row(
        get="302 200 200 404 404 404 302 302 404", post=""
    ),
    "reports/<slug:code>/": Row(get="302 200 200 200 200 404 302 302 200", post=""),
    "api/v1/comparisons/<slug:code>/scores/": Row(
        get="401 200 200 200 200 404 200 401 200", post=""
    ),
    "api/v1/comparisons/<slug:code>/compatibility/": Row(
        get="401 200 200 200 200 404 200 401 200", post="", query="factor=axis"
    ),
    "api/v1/comparisons/<slug:code>/doe-covariance/": Row(
        get="401 403 403 403 200 404 403 401 200", post=""
    ),
    "api/v1/comparisons/<slug:code>/participants/<str:participant>/scope/": Row(
        get="401 403 403 403 200 404 403 401 200",
        post="401 405 405 405 405 405 405 401 405",
        other={"PUT": "401 403 403 403 200 404 403 401 200"},
    ),
    "api/v1/comparisons/<slug:code>/reports/": Row(
        get="401 200 200 200 200 404 200 401 200", post=""
    ),
    "api/v1/reports/<str:token>/pdf": Row(get="401 200 200 404 200 404 200 401 200", post=""),
}
