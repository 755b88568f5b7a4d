"""What a coordinator's action will do, said before it is done: the confirmation pages of
open, close, run and publish (docs/lifecycles.md, the comparison's life cycle), of
accepting every complete submission at once (docs/lifecycles.md §2) and of reissuing a
report (docs/lifecycles.md §4).

Each action's page states its consequences with the round's own numbers (how many
laboratories are e-mailed, how many submissions are analysed, what cannot be undone) and
posts to the action's own URL: the actions themselves are unchanged, so the API and
scripted clients are not affected."""

from __future__ import annotations

from dataclasses import dataclass, field

from django.urls import reverse

from analysis.models import Report
from analysis.publication import publish_refusal
from analysis.selectors import current_run
from common.errors import NotVisible
from common.sizes import counted
from labs.models import Submission
from labs.notices import laboratories_with_addressees
from labs.selectors import acceptable_submissions, current_submissions
from proficiency.models import Comparison, ComparisonStatus
from proficiency.services import comparison_allowed_transitions

S = ComparisonStatus
ACTIONS = ("open", "close", "run", "publish", "accept-complete", "reissue")


@dataclass(frozen=True)
class Confirmation:
    """A confirmation page: what the button does and its consequences, sentence by sentence."""

    title: str
    button: str
    action: str  # the URL the form posts to
    consequences: list[str]
    fields: dict[str, str] = field(default_factory=dict)  # hidden form fields
    final: bool = False  # cannot be undone: the button is red
    refused: str = ""  # why the action is not possible now (no form then)
    back: str = ""  # where Cancel leads (the comparison's page when empty)


def confirmation(comparison: Comparison, action: str, report: str = "") -> Confirmation:
    """The page of ``action`` (one of :data:`ACTIONS`) for ``comparison``; ``report``, for
    a reissue: ``summary`` or a participant's code."""
    if action == "reissue":
        return _reissue(comparison, report or "summary")
    return {
        "open": _open,
        "close": _close,
        "run": _run,
        "publish": _publish,
        "accept-complete": _accept_complete,
    }[action](comparison)


def _labs(comparison: Comparison) -> str:
    return counted(
        comparison.participants.count(), "participating laboratory", "participating laboratories"
    )


def _open(c: Comparison) -> Confirmation:
    reopen = c.status == S.CLOSED
    deadline = c.submission_deadline
    when = (
        f"until the deadline, {deadline:%Y-%m-%d %H:%M %Z}" if deadline else "with no deadline set"
    )
    told = (
        "The laboratories are e-mailed that the round is open again only if its deadline changed."
        if reopen
        else f"{_labs(c)} are e-mailed that the round is open, with a link to it."
    )
    return Confirmation(
        title=f"{'Reopen' if reopen else 'Open'} {c.code} for submissions",
        button="Reopen for submissions" if reopen else "Open for submissions",
        action=reverse("coordinator:status", args=[c.code]),
        fields={"to": S.OPEN},
        consequences=[
            f"Participants can save, upload and submit results {when}.",
            told,
            "You can close the round again at any time.",
        ],
        refused="" if S.OPEN in comparison_allowed_transitions(c) else _not_now(c, "opened"),
    )


def _close(c: Comparison) -> Confirmation:
    n = c.participants.count()
    sent = current_submissions(c, statuses=tuple(Submission.Status)).exclude(
        status=Submission.Status.DRAFT
    )
    submitted = sent.values("participant").distinct().count()
    return Confirmation(
        title=f"Close {c.code} for submissions",
        button="Close submissions",
        action=reverse("coordinator:status", args=[c.code]),
        fields={"to": S.CLOSED},
        consequences=[
            f"{submitted} of {counted(n, 'participant')} have submitted; "
            "nobody can save or submit results after this.",
            "Nobody is e-mailed. You can reopen the round (for example to extend the deadline).",
        ],
        refused="" if S.CLOSED in comparison_allowed_transitions(c) else _not_now(c, "closed"),
    )


def _run(c: Comparison) -> Confirmation:
    accepted = current_submissions(c).count()
    refused = ""
    if c.status not in (S.CLOSED, S.ANALYSED):
        refused = (
            f"{c.code} is {c.get_status_display().lower()}: close it before running the analysis."
        )
    return Confirmation(
        title=f"Run the analysis of {c.code}",
        button="Run analysis",
        action=reverse("coordinator:run_start", args=[c.code]),
        consequences=[
            f"The analysis computes assigned values, scores and compatibility from "
            f"{counted(accepted, 'accepted submission')} (each participant's latest accepted "
            "version) with the round's settings, in the background.",
            "When it succeeds its results become the ones shown to you; earlier runs stay "
            "browsable. Nothing is shown to the participants and nobody is e-mailed.",
        ],
        refused=refused,
    )


def _publish(c: Comparison) -> Confirmation:
    run = current_run(c)
    n = c.participants.count()
    preliminary = (
        Report.objects.filter(comparison=c, superseded=False)
        .exclude(status=Report.Status.FINAL)
        .count()
    )
    refused = ""
    if run is None:
        refused = f"{c.code} has no successful analysis run to publish."
    elif S.PUBLISHED not in comparison_allowed_transitions(c):
        refused = _not_now(c, "published")
    elif (missing := publish_refusal(c)) is not None:
        refused = missing
    return Confirmation(
        title=f"Publish the results of {c.code}",
        button="Publish results",
        action=reverse("coordinator:publish", args=[c.code]),
        final=True,
        consequences=[
            f"The results of analysis run {run.pk if run else '—'} become visible to the "
            f"{_labs(c)}, each seeing the others by code only.",
            f"{counted(n, 'laboratory', 'laboratories')} are e-mailed, with links to their "
            "results and reports.",
            f"The final reports are rendered in the background first (the summary and "
            f"{counted(n, 'participant report')}); the results are published, and the "
            "laboratories e-mailed, only once every report is ready, and nothing is if one "
            "fails"
            + (
                f"; {counted(preliminary, 'preliminary report')} "
                f"{'is' if preliminary == 1 else 'are'} superseded by them."
                if preliminary
                else "."
            ),
            "Publication is final: it cannot be undone. A correction afterwards is a "
            "reissued report.",
        ],
        refused=refused,
    )


def _not_now(c: Comparison, done: str) -> str:
    return f"{c.code} is {c.get_status_display().lower()}: it cannot be {done} now."


def _accept_complete(c: Comparison) -> Confirmation:
    rows = acceptable_submissions(c)
    codes = [row.participant.code for row in rows]
    labs = {row.participant.laboratory_id for row in rows}
    mailed = len(laboratories_with_addressees(list(labs)))
    inbox_only = len(labs) - mailed
    told = (
        "1 laboratory is e-mailed that its submission is accepted"
        if mailed == 1
        else f"{counted(mailed, 'laboratory', 'laboratories')} are e-mailed that their "
        "submission is accepted"
    )
    if inbox_only:
        told += (
            f"; {counted(inbox_only, 'laboratory', 'laboratories')} without an e-mail address "
            "will find the notice in the inbox only"
        )
    return Confirmation(
        title=f"Accept {counted(len(rows), 'complete submission')} of {c.code}",
        button=f"Accept {counted(len(rows), 'submission')}",
        action=reverse("coordinator:accept_complete", args=[c.code]),
        fields={"expected": ",".join(codes)},
        back=reverse("coordinator:review", args=[c.code]),
        consequences=[
            f"Accepted: {', '.join(codes)}: each participant's latest version, submitted and "
            "not yet decided, with a result at every point of the participant's scope and no "
            "request to check a result.",
            told + ".",
            "An accepted version is final; a correction is a new version. If a submission "
            "arrives or is withdrawn before you confirm, the button accepts what is complete "
            "then and says what changed.",
        ],
        refused=""
        if rows
        else (
            f"No submission of {c.code} is complete and waiting for a decision: nothing to accept."
        ),
    )


def _reissue(c: Comparison, which: str) -> Confirmation:
    """A new version of one report from the current run (the summary, or ``which``'s)."""
    participant = None if which == "summary" else c.participants.filter(code=which).first()
    if which != "summary" and participant is None:
        raise NotVisible(f"No participant {which!r} in {c.code}.")
    name = "the summary report" if participant is None else f"participant report {which}"
    kind = Report.Kind.SUMMARY if participant is None else Report.Kind.PARTICIPANT
    previous = Report.objects.filter(comparison=c, kind=kind, participant=participant)
    last = previous.order_by("-version").first()
    run = current_run(c)
    status = "final" if c.status == S.PUBLISHED else "preliminary"
    refused = ""
    if run is None:
        refused = f"{c.code} has no successful analysis run to issue a report from."
    elif c.status not in (S.ANALYSED, S.PUBLISHED):
        refused = f"{c.code} is {c.get_status_display().lower()}: reports are issued once analysed."
    version = (last.version if last else 0) + 1
    return Confirmation(
        title=f"Reissue {name} of {c.code}",
        button=f"Issue version {version}",
        action=reverse("reports_reissue", args=[c.code]),
        fields={"report": which},
        back=reverse("reports", args=[c.code]),
        consequences=[
            f"Version {version} of {name} is rendered now from analysis run "
            f"{run.pk if run else '—'}, with the current comments and authorisation, "
            f"as a {status} report.",
            (f"Version {last.version} stays downloadable, marked superseded."
             if last else "It is the first version of this report."),
            ("The participant sees the new version on its reports page; nobody is e-mailed."
             if participant is not None and status == "final" else
             "The participants see it once the results are published; nobody is e-mailed."
             if status != "final" else
             "Every participant sees the new summary on its reports page; nobody is e-mailed."),
        ],
        refused=refused,
    )  # fmt: skip
