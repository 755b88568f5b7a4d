#!/usr/bin/env bash
# Renders the demo comparison's reports and rasterises their first two pages into
# docs/samples/ (for reviewers).  Embedded settings: a throw-away SQLite database, Celery
# eager.  Needs poppler-utils (pdftoppm).  Run from the repository root:
#   bash docs/make_samples.sh
set -euo pipefail
cd "$(dirname "$0")/.."
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
export DATABASE_URL="sqlite:///$work/db.sqlite3" MEDIA_ROOT="$work/media"
unset CELERY_BROKER_URL
.venv/bin/python manage.py migrate --noinput >/dev/null
.venv/bin/python manage.py load_demo >/dev/null
.venv/bin/python manage.py shell -c "
from analysis.models import Report
from analysis.services import analysis_run_start
from proficiency.models import Comparison, ComparisonStatus
from analysis.publication import comparison_publish
from proficiency.services import comparison_transition
c = Comparison.objects.get(code='IMU-2024-DEMO')
if c.status == ComparisonStatus.OPEN:
    comparison_transition(comparison=c, to=ComparisonStatus.CLOSED)
analysis_run_start(comparison=c, user=None)
comparison_publish(comparison=Comparison.objects.get(pk=c.pk))
summary = Report.objects.get(comparison=c, kind='summary', superseded=False)
first = Report.objects.filter(comparison=c, kind='participant', superseded=False).order_by('participant__code').first()
open('$work/paths', 'w').write(summary.file.path + '\n' + first.file.path + '\n')
"
mapfile -t pdfs < "$work/paths"
pdftoppm -r 60 -png -f 1 -l 2 "${pdfs[0]}" docs/samples/summary
pdftoppm -r 60 -png -f 1 -l 2 "${pdfs[1]}" docs/samples/participant
ls -l docs/samples/
