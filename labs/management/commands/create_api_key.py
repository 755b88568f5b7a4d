"""python manage.py create_api_key --lab LAB [--name NAME] — a new API key, printed once."""

from django.core.management.base import BaseCommand, CommandError

from common.errors import ApplicationError
from common.sizes import database_id
from labs.models import Laboratory
from labs.services import api_key_create


def _laboratory(ref: str) -> Laboratory:
    """By exact name, else by id (a laboratory named with digits still wins by name)."""
    lab = Laboratory.objects.filter(name=ref).first()
    if lab is None and (pk := database_id(ref)) is not None:
        lab = Laboratory.objects.filter(pk=pk).first()
    if lab is None:
        raise CommandError(f"No laboratory named {ref!r} or with that id.", returncode=2)
    return lab


class Command(BaseCommand):
    help = (
        "Create an API key for a laboratory's software (Authorization: Api-Key <key>). "
        "The key is printed once: only its hash is stored."
    )

    def add_arguments(self, parser):
        parser.add_argument("--lab", required=True, help="laboratory name or id")
        parser.add_argument("--name", default="lab software", help="what uses the key")

    def handle(self, *args, lab, name, **options):
        laboratory = _laboratory(lab)
        try:
            key_obj, key = api_key_create(laboratory=laboratory, name=name, user=None)
        except ApplicationError as exc:
            raise CommandError(exc.message, returncode=2) from None
        self.stderr.write(
            f"API key {key_obj.prefix} ({key_obj.name!r}) created for {laboratory.name}. "
            "Store it now; it cannot be shown again."
        )
        self.stdout.write(key)
