"""A sentence that introduces a table is never the last line of a page (docs/domain.md §9):
the history section's "Your laboratory took part in n rounds" stays on the page of the
rounds' first row.  No database: a hand-made participant report, its title block padded a
line at a time so that the sentence falls at the foot of page 1 for some padding; read
back per page with pypdf."""

import dataclasses
from datetime import UTC, datetime

from analysis.reports import render
from analysis.reports.data import HistoryPoint, HistoryRound, ReportData, ReportHistory
from analysis.reports.render import render_report
from tests.analysis.reports.conftest import pdf_text
from tests.analysis.reports.test_visual import small_round

INTRO = "Your laboratory took part in 3 rounds up to this one."
FIRST_ROW = "R-2021-FIRST"


def with_history(pad: int) -> ReportData:
    rounds = tuple(
        HistoryRound(code, datetime(2021 + i, 5, 1, tzinfo=UTC), f"L{i}2", 8, 9, 7, 9)
        for i, code in enumerate((FIRST_ROW, "R-2022-SECOND", "T-1"))
    )
    history = ReportHistory(rounds, (HistoryPoint("LSM6DSR, X, 5 Hz", 3, 0.5, "S", 0.9, "S"),))
    address = " ".join(["Street"] * pad)  # wraps in the title table: a line per ~15 words
    return dataclasses.replace(small_round(), history=history, provider_address=address)


def split_at(pads: range) -> list[int]:
    """The paddings whose page ending the intro sentence does not hold the first row."""
    found = []
    for pad in pads:
        pages = [" ".join(t.split()) for t in pdf_text(render_report(with_history(pad)))]
        at = [i for i, t in enumerate(pages) if INTRO in t]
        row = [i for i, t in enumerate(pages) if FIRST_ROW in t]
        assert len(at) == 1 and row, pad
        if at[0] != row[0]:
            found.append(pad)
    return found


def test_the_intro_sentence_stays_with_the_first_row_of_its_table(monkeypatch):
    pads = range(260, 340, 6)  # under a line a step: the sentence passes the foot of page 1
    assert split_at(pads) == []
    # without keeping intro sentences with what follows (headings only), some split
    monkeypatch.setattr(render, "KEEP_WITH_NEXT", frozenset({"h1", "h2"}))
    assert split_at(pads)
