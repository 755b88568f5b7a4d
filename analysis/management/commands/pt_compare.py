"""python manage.py pt_compare RESULTS.csv — analyse a results table offline
(docs/interfaces.md §4).

No database or server is used: the file is checked as the web upload checks it, but
without the upload's size and row limits (a local file may be a whole national round),
by :func:`labs.importers.local.read_local_table`; the numbers come from
``analysis.pipeline``.  Bad input: exit code 2, the first 1,000 problems and the count of
the rest on standard error, nothing written.  Standard output holds the requested output
only (``manage.py`` runs it without ``django.setup()``, see ``STANDALONE_COMMANDS`` there).
"""

import contextlib
import gc
from collections.abc import Iterator
from pathlib import Path

from django.core.management.base import BaseCommand, CommandError

from analysis.core.groups import CoreInputError
from analysis.offline import approximate_points, approximate_warning, output_sink, write
from analysis.pipeline import FACTORS, AssignedSpec, ResultTable, SigmaPtSpec, analyse
from labs.importers import ImportErrors
from labs.importers.local import LocalTable, read_local_table

BY_KEYS = ("lab", "device", "axis", "frequency", "frequency_hz", "bench", "direction")


class Command(BaseCommand):
    help = "Assigned values, scores and compatibility matrices of a results table (CSV/XLSX)."
    requires_system_checks: list[str] = []
    requires_migrations_checks = False

    def add_arguments(self, parser):
        parser.add_argument("results", help="CSV or XLSX results table with a 'lab' column")
        parser.add_argument(
            "--assigned",
            default="weighted-mean",
            help="reference:<LAB> | nominal:<value>:<tolerance>[%%][:rect|:normal] | "
            "weighted-mean (default) | algorithm-a | median (MADe) | median-niqr | q-hampel | "
            "dersimonian-laird",
        )
        parser.add_argument(
            "--compare", action="append", default=[], choices=FACTORS,
            help="factor whose levels are compared (repeatable)",
        )  # fmt: skip
        parser.add_argument(
            "--by", action="append", default=None, choices=BY_KEYS,
            help="grouping key of the matrices (repeatable; default device and axis, "
            "for lab the whole measurement point)",
        )  # fmt: skip
        parser.add_argument(
            "--sigma-pt", default=None,
            help="σ_pt for z scores: a value, a percentage of x_pt (e.g. 1%%), or robust",
        )  # fmt: skip
        parser.add_argument("--en-limit", type=float, default=1.0)
        parser.add_argument("--format", choices=["table", "json", "csv"], default="table")
        parser.add_argument("--output", help="write to this file instead of standard output")
        parser.add_argument(
            "--indent", type=int, default=None, metavar="N",
            help="JSON only: indented by N spaces, for reading (default: compact, one line)",
        )  # fmt: skip

    def handle(self, *args, **opts):
        try:
            spec = AssignedSpec.parse(opts["assigned"])
            sigma = SigmaPtSpec.parse(opts["sigma_pt"])
        except ValueError as exc:
            raise CommandError(str(exc), returncode=2) from None
        if opts["indent"] is not None and not 0 <= opts["indent"] <= 16:
            raise CommandError("--indent takes a number of spaces from 0 to 16", returncode=2)
        path = Path(opts["results"])
        table = _read(path)
        by = [b.replace("frequency_hz", "frequency") for b in opts["by"]] if opts["by"] else None
        compare = [(f, [b for b in by if b != f] if by else None) for f in opts["compare"]]
        try:
            result = analyse(
                result_table(table), spec, sigma_pt=sigma,
                en_limit=opts["en_limit"], compare=compare,
            )  # fmt: skip
        except CoreInputError as exc:
            raise CommandError(f"{path} could not be analysed: {exc}", returncode=2) from None
        if n := approximate_points(result):
            self.stderr.write(approximate_warning(n))
        try:
            with output_sink(opts["output"], self.stdout) as sink, _gc_paused():
                write(result, opts["format"], sink, indent=opts["indent"])
        except OSError as exc:
            where = opts["output"] or "standard output"
            raise CommandError(f"{where} cannot be written: {exc.strerror}", returncode=2) from None


def _read(path: Path) -> LocalTable:
    if not path.is_file():
        raise CommandError(f"{path}: no such file", returncode=2)
    try:
        return read_local_table(path)
    except ImportErrors as exc:
        raise CommandError(f"{path} was not analysed:\n{exc}", returncode=2) from None
    except OSError as exc:
        raise CommandError(f"{path} cannot be read: {exc.strerror}", returncode=2) from None


@contextlib.contextmanager
def _gc_paused() -> Iterator[None]:
    """No cyclic garbage collection while the records are written: hundreds of thousands
    of short-lived containers, none in a cycle; the collector would only walk them."""
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()


def result_table(table: LocalTable) -> ResultTable:
    """The columns the analysis takes (``ResultTable.from_rows`` of the same rows)."""
    return ResultTable(
        lab=table.lab,
        device=table.device,
        axis=table.axis,
        frequency_hz=table.frequency_hz,
        bench=table.bench,
        direction=table.direction,
        value=table.sensitivity,
        expanded_uncertainty=table.expanded_uncertainty,
        coverage_factor=table.coverage_factor,
        repeat_sd=table.repeat_sd,
        n_repeats=table.n_repeats,
        quantity=table.quantity,
    )
