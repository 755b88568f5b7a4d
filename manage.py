#!/usr/bin/env python
"""Django's command-line utility for administrative tasks."""

import os
import sys
from importlib import import_module

#: Commands that need no Django project: no settings, no database, no installed app
#: (docs/interfaces.md §4). They run without ``django.setup()``, which would import every installed
#: app (0.4 s, as long as reading a 200,000-row results table) and let them log at start-up
#: (django-axes' "AXES: BEGIN" line) before the command's own output. Logging of the web
#: service, the workers and every other command is untouched.
STANDALONE_COMMANDS = {"pt_compare": "analysis.management.commands.pt_compare"}


def main() -> None:
    if len(sys.argv) > 1 and sys.argv[1] in STANDALONE_COMMANDS:
        import_module(STANDALONE_COMMANDS[sys.argv[1]]).Command().run_from_argv(sys.argv)
        return
    os.environ.setdefault("DJANGO_SETTINGS_MODULE", "config.settings")
    from django.core.management import execute_from_command_line

    execute_from_command_line(sys.argv)


if __name__ == "__main__":
    main()
