"""Who reads a results page (docs/architecture.md §3.1): the comparison, the run shown, the
audience and the reader's own code. Below the views, so that the chart warming task
(``analysis.chart_page``) draws for the same reader as the charts page."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

from django.urls import reverse

from analysis.models import AnalysisRun
from analysis.selectors import current_run
from proficiency.models import Comparison

COORDINATOR, PARTICIPANT = "coordinator", "participant"


@dataclass(frozen=True)
class Viewer:
    """Who reads a results page: the comparison, the run shown, the own code to highlight."""

    comparison: Comparison
    run: AnalysisRun | None
    audience: str
    own_code: str | None = None

    @property
    def is_coordinator(self) -> bool:
        return self.audience == COORDINATOR

    @cached_property
    def current(self) -> AnalysisRun | None:
        """The comparison's current run, read once per page (every tab's link needs it)."""
        return current_run(self.comparison)

    def url(self, page: str) -> str:
        prefix = "" if self.is_coordinator else "lab_"
        url = reverse(f"coordinator:{prefix}{page}", args=[self.comparison.code])
        current = self.current
        if self.is_coordinator and self.run and current and self.run.pk != current.pk:
            url += f"?run={self.run.pk}"
        return url

    def nav(self) -> list[tuple[str, str, str]]:
        pages = [("results", "Assigned values"), ("scores", "Scores"), ("charts", "Charts"),
                 ("compatibility", "Compatibility"), ("consistency", "Consistency")]  # fmt: skip
        if self.is_coordinator:
            pages.insert(1, ("performance", "Performance"))
        if self.run is not None and self.run.kit_points.exists():  # docs/domain.md §14
            pages.append(("results_kits", "Kits and linking"))
        return [(page, label, self.url(page)) for page, label in pages]
