"""Locust scenario of the load test; run through ``bench/bench_load.py``.

Reads the fixture written by ``bench_load.py setup`` (``LOAD_FIXTURE``, default
``/tmp/pt-load/fixture.json``): one API key per laboratory, the coordinators'
passwords and the rows of one complete submission.

* ``LabUser`` (all users but two): one laboratory each, authenticated by its own
  API key; submits JSON results to ``LOAD-OPEN`` (1 request in 14; three in four
  submitted, one in four saved as a draft) and polls the comparison list, the comparison, its
  measurands, its submission history and the latest version's detail. Paced by
  ``constant_throughput(LAB_RPS)`` (default 5 requests/s per lab = 300/min, half
  the default ``THROTTLE_API_KEY`` of 600/min, so the throttle never answers 429).
* ``CoordinatorUser`` (exactly two): logs in through the web form (CSRF token,
  correct password: django-axes never locks), starts an analysis run of
  ``LOAD-CLOSED`` through the API (session + CSRF), polls the run every second
  until it succeeds (a failed run, or one not done within ``RUN_TIMEOUT_S``,
  counts as a failure), then reads the run list and the scores, and waits a few
  seconds before the next run. At most ~1.5 requests/s per user, far below
  ``THROTTLE_USER``.

Every answer other than the expected status is a failure in the statistics.
"""

from __future__ import annotations

import itertools
import json
import os
import random
import time
from pathlib import Path
from typing import Any

from locust import FastHttpUser, between, constant_throughput, task

FIXTURE = json.loads(Path(os.environ.get("LOAD_FIXTURE", "/tmp/pt-load/fixture.json")).read_text())
LAB_RPS = float(os.environ.get("LAB_RPS", "5"))
RUN_TIMEOUT_S = 120
API = "/api/v1"
_labs = itertools.cycle(FIXTURE["labs"])
_coordinators = itertools.cycle(FIXTURE["coordinators"])


def results(rng: random.Random) -> list[dict]:
    """A complete, plausible results table: sensitivity ≈ 418 with lab bias and noise."""
    bias = rng.gauss(0, 0.004)
    return [
        row | {"sensitivity": round(418 * (1 + bias + rng.gauss(0, 0.0025)), 2),
               "expanded_uncertainty": round(418 * rng.uniform(0.012, 0.024), 2)}
        for row in FIXTURE["records"]
    ]  # fmt: skip


class LabUser(FastHttpUser):
    weight = 1
    wait_time = constant_throughput(LAB_RPS)

    def on_start(self) -> None:
        lab = next(_labs)
        self.headers = {"Authorization": f"Api-Key {lab['key']}"}
        self.code = FIXTURE["open"]
        self.rng = random.Random(lab["lab"])
        self.version = 1

    def _get(self, path: str, name: str) -> Any:  # the JSON answer, None on failure
        with self.client.get(path, headers=self.headers, name=name, catch_response=True) as r:
            if r.status_code != 200:
                r.failure(f"HTTP {r.status_code}: {r.text[:200]}")
                return None
            return r.json()

    @task(3)
    def comparison_list(self) -> None:
        self._get(f"{API}/comparisons/", f"{API}/comparisons/")

    @task(3)
    def comparison_detail(self) -> None:
        self._get(f"{API}/comparisons/{self.code}/", f"{API}/comparisons/[code]/")

    @task(1)
    def measurands(self) -> None:
        self._get(
            f"{API}/comparisons/{self.code}/measurands/", f"{API}/comparisons/[code]/measurands/"
        )

    @task(4)
    def history(self) -> None:
        page = self._get(
            f"{API}/comparisons/{self.code}/submissions/", f"{API}/comparisons/[code]/submissions/"
        )
        if page and page["results"]:
            self.version = max(s["version"] for s in page["results"])

    @task(2)
    def submission_detail(self) -> None:
        self._get(
            f"{API}/comparisons/{self.code}/submissions/{self.version}/",
            f"{API}/comparisons/[code]/submissions/[version]/",
        )

    @task(1)
    def submit(self) -> None:
        body = {"results": results(self.rng), "submit": self.rng.random() < 0.75}
        with self.client.post(
            f"{API}/comparisons/{self.code}/submissions/", json=body, headers=self.headers,
            name=f"{API}/comparisons/[code]/submissions/", catch_response=True,
        ) as r:  # fmt: skip
            if r.status_code != 201:
                r.failure(f"HTTP {r.status_code}: {r.text[:300]}")
                return
            s = r.json()
            if s["n_results"] != len(FIXTURE["records"]):
                r.failure(f"stored {s['n_results']} results, sent {len(FIXTURE['records'])}")
            self.version = s["version"]


class CoordinatorUser(FastHttpUser):
    fixed_count = 2
    wait_time = between(5, 10)

    def on_start(self) -> None:
        who = next(_coordinators)
        self.code = FIXTURE["closed"]
        self.client.get("/accounts/login/", name="/accounts/login/")
        token = self.client.cookiejar  # FastHttpSession keeps cookies like a browser
        csrf = _cookie(token, "csrftoken")
        with self.client.post(
            "/accounts/login/", name="/accounts/login/", catch_response=True,
            data={"username": who["username"], "password": who["password"],
                  "csrfmiddlewaretoken": csrf},
            headers={"Referer": f"{self.host}/accounts/login/"}, allow_redirects=False,
        ) as r:  # fmt: skip
            if r.status_code != 302 or not _cookie(self.client.cookiejar, "sessionid"):
                r.failure(f"login failed: HTTP {r.status_code}")
        self.headers = {"X-CSRFToken": _cookie(self.client.cookiejar, "csrftoken"),
                        "Referer": f"{self.host}/"}  # fmt: skip

    @task
    def analyse(self) -> None:
        with self.client.post(
            f"{API}/comparisons/{self.code}/analysis-runs/", headers=self.headers,
            name=f"{API}/comparisons/[code]/analysis-runs/", catch_response=True,
        ) as r:  # fmt: skip
            if r.status_code != 202:
                r.failure(f"HTTP {r.status_code}: {r.text[:300]}")
                return
            run = r.json()
        started = time.monotonic()
        while run["status"] not in ("succeeded", "failed"):
            if time.monotonic() - started > RUN_TIMEOUT_S:
                self._fail("analysis run", f"run {run['id']} not done in {RUN_TIMEOUT_S} s")
                return
            time.sleep(1)  # gevent-patched: yields to the other users
            with self.client.get(
                f"{API}/analysis-runs/{run['id']}/", name=f"{API}/analysis-runs/[id]/",
                catch_response=True,
            ) as r:  # fmt: skip
                if r.status_code != 200:
                    r.failure(f"HTTP {r.status_code}: {r.text[:200]}")
                    return
                run = r.json()
        if run["status"] != "succeeded":
            self._fail("analysis run", f"run {run['id']} failed: {run.get('error', '')[:200]}")
            return
        self.client.get(f"{API}/comparisons/{self.code}/analysis-runs/",
                        name=f"{API}/comparisons/[code]/analysis-runs/")  # fmt: skip
        self.client.get(f"{API}/comparisons/{self.code}/scores/?device=MEMS+2",
                        name=f"{API}/comparisons/[code]/scores/")  # fmt: skip

    def _fail(self, name: str, message: str) -> None:
        self.environment.events.request.fire(
            request_type="RUN", name=name, response_time=0, response_length=0,
            exception=RuntimeError(message), context={},
        )  # fmt: skip


def _cookie(jar: object, name: str) -> str:
    for cookie in jar:  # type: ignore[attr-defined]
        if cookie.name == name:
            return cookie.value
    return ""
