"""examples/lab_client.py against a live server: list, template, submit, row errors."""

import importlib.util
from pathlib import Path

import pytest
from django.core.cache import cache

from labs.models import Submission
from tests.labs.api import as_csv, build_world, rows

EXAMPLE = Path(__file__).resolve().parents[3] / "examples" / "lab_client.py"


@pytest.fixture
def lab_client():
    spec = importlib.util.spec_from_file_location("lab_client", EXAMPLE)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture
def world(transactional_db):
    cache.clear()
    return build_world()


def test_lab_client_end_to_end(live_server, world, lab_client, tmp_path, capsys):
    base = ["--url", live_server.url, "--key", world.keys["key_a"], "--comparison", "IMU-A-01"]
    template = tmp_path / "template.csv"
    bad = tmp_path / "bad.csv"
    bad_rows = rows()
    bad_rows[1]["expanded_uncertainty"] = -3
    bad.write_bytes(as_csv(bad_rows))
    assert lab_client.main([*base, "--template", str(template), "--file", str(bad)]) == 1
    out, err = capsys.readouterr()
    assert "IMU-A-01" in out and "IMU-AB-01" in out
    assert template.read_bytes().startswith(b"\xef\xbb\xbfdevice,axis")
    assert "HTTP 400" in err and "row 3, column expanded_uncertainty: must be > 0" in err

    good = tmp_path / "good.csv"
    good.write_bytes(as_csv(rows()))
    assert lab_client.main([*base, "--file", str(good)]) == 0
    out = capsys.readouterr().out
    assert "stored: L17 version 2, submitted, 4 results" in out
    key = out.split("Idempotency-Key: ")[1].split()[0]
    assert len(key) == 36  # a UUID
    assert Submission.objects.filter(participant=world.part_a).count() == 2
    # run again with the printed key (after a crash, say): the same version, nothing stored
    again = [*base, "--file", str(good), "--idempotency-key", key]
    assert lab_client.main(again) == 0
    assert "stored: L17 version 2, submitted, 4 results" in capsys.readouterr().out
    assert Submission.objects.filter(participant=world.part_a).count() == 2


def test_lab_client_sends_again_with_the_same_key_after_a_502(lab_client, tmp_path, monkeypatch):
    """A 502 from the proxy, then success: two POSTs with one Idempotency-Key."""
    sent: list[str] = []

    class Answer:
        def __init__(self, status: int) -> None:
            self.status_code = status

    def post(url, files, data, headers, timeout):
        sent.append(headers["Idempotency-Key"])
        return Answer(502 if len(sent) == 1 else 201)

    api = lab_client.Api("http://127.0.0.1:9", "key")
    monkeypatch.setattr(api.session, "post", post)
    monkeypatch.setattr(lab_client.time, "sleep", lambda s: None)
    path = tmp_path / "r.csv"
    path.write_bytes(b"x")
    assert api.upload("IMU-A-01", path, submit=True, key="k-1").status_code == 201
    assert sent == ["k-1", "k-1"]


def test_lab_client_reports_a_revoked_key(live_server, world, lab_client, capsys):
    with pytest.raises(SystemExit) as exit_:
        lab_client.main(["--url", live_server.url, "--key", world.keys["revoked_key_a"]])
    assert exit_.value.code == 1
    assert "HTTP 401" in capsys.readouterr().err
