"""python manage.py import_results CODE FILE [--user USERNAME] — a coordinator's bulk import."""

import time

from django.contrib.auth import get_user_model
from django.core.management.base import BaseCommand, CommandError

from common.errors import ApplicationError
from labs.bulk_import import ImportRefused, results_import
from labs.importers.errors import more_problems
from proficiency.models import Comparison


class Command(BaseCommand):
    help = (
        "Import the results of many participants of a comparison from one CSV/XLSX results "
        "table (the upload's columns, the lab column holding each row's participant code): one "
        "new submitted version per participant, all or nothing. Exit status 2 with every problem "
        "listed when the file is refused."
    )

    def add_arguments(self, parser):
        parser.add_argument("code", help="comparison code, e.g. IMU-2024-DEMO")
        parser.add_argument("file", help="CSV or XLSX results table with a lab column")
        parser.add_argument(
            "--user", help="the coordinator importing (recorded in the audit log); default: none"
        )

    def handle(self, *args, code, file, user=None, **options):
        comparison = Comparison.objects.filter(code=code).first()
        if comparison is None:
            raise CommandError(f"No comparison with code {code!r}.", returncode=2)
        actor = None
        if user is not None:
            actor = get_user_model().objects.filter(username=user).first()
            if actor is None:
                raise CommandError(f"No user {user!r}.", returncode=2)
        started = time.perf_counter()
        try:
            summary = results_import(comparison=comparison, file=file, user=actor)
        except FileNotFoundError:
            raise CommandError(f"No file {file}.", returncode=2) from None
        except ImportRefused as exc:
            for error in exc.row_errors:
                self.stderr.write(str(error))
            more = more_problems(exc.total - len(exc.row_errors))
            if more:
                self.stderr.write(more)
            raise CommandError(exc.message, returncode=2) from None
        except ApplicationError as exc:
            raise CommandError(exc.message, returncode=2) from None
        seconds = time.perf_counter() - started
        self.stdout.write(
            f"{summary.comparison}: {summary.rows:,} results of {summary.participants:,} "
            f"participants imported in {seconds:.1f} s ({summary.new_versions:,} new versions, "
            f"{summary.drafts_submitted:,} drafts submitted)"
        )
