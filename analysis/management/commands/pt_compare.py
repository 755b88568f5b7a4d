"""python manage.py pt_compare RESULTS.csv — analyse a results table offline (formats.md §4).

No database or server is used: the file is read by the same importer as the web
upload, the numbers come from ``analysis.pipeline``. Exit code 2 on bad input.
"""

from pathlib import Path

from django.core.management.base import BaseCommand, CommandError

from analysis.core.groups import CoreInputError
from analysis.offline import approximate_points, approximate_warning, render, write_output
from analysis.pipeline import FACTORS, AssignedSpec, ResultTable, SigmaPtSpec, analyse
from labs.importers import ImportErrors, parse_table

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
            "weighted-mean (default) | algorithm-a | median | dersimonian-laird",
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

    def handle(self, *args, **opts):
        try:
            spec = AssignedSpec.parse(opts["assigned"])
            sigma = SigmaPtSpec.parse(opts["sigma_pt"])
        except ValueError as exc:
            raise CommandError(str(exc), returncode=2) from None
        path = Path(opts["results"])
        if not path.is_file():
            raise CommandError(f"{path}: no such file", returncode=2)
        try:
            rows = parse_table(path.read_bytes(), filename=path.name, lab_column="required")
        except ImportErrors as exc:
            raise CommandError(f"{path} was not analysed:\n{exc}", returncode=2) from None
        by = [b.replace("frequency_hz", "frequency") for b in opts["by"]] if opts["by"] else None
        compare = [(f, [b for b in by if b != f] if by else None) for f in opts["compare"]]
        try:
            result = analyse(
                ResultTable.from_rows(rows), spec, sigma_pt=sigma,
                en_limit=opts["en_limit"], compare=compare,
            )  # fmt: skip
        except CoreInputError as exc:
            raise CommandError(f"{path} could not be analysed: {exc}", returncode=2) from None
        if n := approximate_points(result):
            self.stderr.write(approximate_warning(n))
        write_output(render(result, opts["format"]), opts["output"], self.stdout)
