#!/usr/bin/env bash
# Renders the demo comparisons' reports and rasterises pages of them into docs/samples/ (for
# reviewers): the first two pages of IMU-2024-DEMO's summary and of its first participant's
# report, and the "Linking and drift" pages of the two-kit round IMU-2025-KITS (summary and
# the pilot's report).  Embedded settings: a throw-away SQLite database, Celery
# eager.  Needs poppler-utils (pdftoppm).  Run from the repository root:
#   bash docs/make_samples.sh
set -euo pipefail
cd "$(dirname "$0")/.."
work=$(mktemp -d)
trap '[ -n "${KEEP:-}" ] || rm -rf "$work"' EXIT
export DATABASE_URL="sqlite:///$work/db.sqlite3" MEDIA_ROOT="$work/media"
unset CELERY_BROKER_URL
.venv/bin/python manage.py migrate --noinput >/dev/null
.venv/bin/python manage.py load_demo >/dev/null
.venv/bin/python manage.py shell >/dev/null -c "
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
kits = Comparison.objects.get(code='IMU-2025-KITS')
comparison_publish(comparison=kits)
ks = Report.objects.get(comparison=kits, kind='summary', superseded=False)
kp = Report.objects.filter(comparison=kits, kind='participant', superseded=False).order_by('participant__code').first()
open('$work/paths', 'w').write('\n'.join(r.file.path for r in (summary, first, ks, kp)) + '\n')
"
mapfile -t pdfs < "$work/paths"
pdftoppm -r 60 -png -f 1 -l 2 "${pdfs[0]}" docs/samples/summary
pdftoppm -r 60 -png -f 1 -l 2 "${pdfs[1]}" docs/samples/participant
# the first page whose text holds the heading, and the one after it
linking_page() {
  local n pages
  pages=$(pdfinfo "$1" | awk '/^Pages:/ {print $2}')
  for ((n = 1; n <= pages; n++)); do
    if [[ $'\n'$(pdftotext -f "$n" -l "$n" "$1" -) == *$'\nLinking and drift\n'* ]]; then
      echo "$n"; return
    fi
  done
  echo "no 'Linking and drift' page in $1" >&2; return 1
}
rm -f docs/samples/kits-*.png
p=$(linking_page "${pdfs[2]}")
pdftoppm -r 60 -png -f "$p" -l $((p + 1)) "${pdfs[2]}" docs/samples/kits-summary
p=$(linking_page "${pdfs[3]}")
pdftoppm -r 60 -png -f "$p" -l $((p + 1)) "${pdfs[3]}" docs/samples/kits-participant
ls -l docs/samples/
