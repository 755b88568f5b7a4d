"""python manage.py export_results CODE — a comparison's accepted results as a results table."""

from django.core.management.base import BaseCommand, CommandError

from labs.importers import write_table
from labs.selectors import comparison_result_rows
from proficiency.models import Comparison


class Command(BaseCommand):
    help = (
        "Write the current accepted results of a comparison as a CSV/XLSX results table "
        "(the upload's columns, labs by anonymous code), e.g. for pt_compare."
    )

    def add_arguments(self, parser):
        parser.add_argument("code", help="comparison code, e.g. IMU-2024-DEMO")
        parser.add_argument("--format", choices=["csv", "xlsx"], default="csv")
        parser.add_argument("--output", help="file to write (default: standard output, CSV only)")

    def handle(self, *args, code, format, output=None, **options):
        comparison = Comparison.objects.filter(code=code).first()
        if comparison is None:
            raise CommandError(f"No comparison with code {code!r}.", returncode=2)
        rows = comparison_result_rows(comparison)
        if not rows:
            raise CommandError(f"Comparison {code} has no accepted results.", returncode=2)
        data = write_table(rows, format=format, bom=False)
        if output:
            with open(output, "wb") as f:
                f.write(data)
            self.stderr.write(f"{len(rows)} results written to {output}")
        elif format == "xlsx":
            raise CommandError("--format xlsx needs --output FILE.", returncode=2)
        else:
            self.stdout.write(data.decode(), ending="")
