#!/usr/bin/env python3
"""Example lab software client for the proficiency-testing REST API (docs/interfaces.md §3).

Lists the comparisons your laboratory takes part in, downloads the results
template of one comparison, submits a results file (CSV or XLSX) and prints
every refused row and column. Needs only the standard library and requests.

    python examples/lab_client.py --url http://127.0.0.1:8000 --key KEY \\
        --comparison IMU-2024-DEMO --file results.csv [--draft] [--template out.csv] \\
        [--idempotency-key KEY]

Every submission carries an ``Idempotency-Key`` (a new UUID, printed, unless one is
given): a request that timed out or hit a server error is sent again with the same key,
and the service answers the version it already stored instead of storing a second one.
After a crash, run the command again with the printed key to the same effect.

The key is created by the laboratory's manager or with
``python manage.py create_api_key --lab "<lab name>"``; it can also be given in the
environment variable PT_API_KEY instead of --key.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
import uuid
from pathlib import Path

import requests

TIMEOUT_S = 120
ATTEMPTS = 3  # a submission is sent at most this often (same Idempotency-Key each time)
RETRY_STATUSES = {502, 503, 504}  # the proxy or the server was not there: safe to resend


class Api:
    def __init__(self, url: str, key: str) -> None:
        self.base = url.rstrip("/") + "/api/v1/"
        self.session = requests.Session()
        self.session.headers["Authorization"] = f"Api-Key {key}"

    def get(self, path: str, **params: str) -> requests.Response:
        return self.session.get(self.base + path, params=params, timeout=TIMEOUT_S)

    def comparisons(self) -> list[dict]:
        """Every page of the comparison list."""
        found, url = [], self.base + "comparisons/"
        while url:
            page = _checked(self.session.get(url, timeout=TIMEOUT_S)).json()
            found += page["results"]
            url = page["next"]
        return found

    def template(self, code: str, fmt: str = "csv") -> bytes:
        return _checked(self.get(f"comparisons/{code}/template.csv", format=fmt)).content

    def upload(self, code: str, path: Path, submit: bool, key: str) -> requests.Response:
        """POST the file; on a timeout, a lost connection or a 502/503/504, send it again
        with the same ``Idempotency-Key`` (the service then stores it at most once)."""
        for attempt in range(1, ATTEMPTS + 1):
            try:
                with path.open("rb") as f:
                    response = self.session.post(
                        f"{self.base}comparisons/{code}/submissions/upload/",
                        files={"file": (path.name, f)},
                        data={"submit": "true" if submit else "false"},
                        headers={"Idempotency-Key": key},
                        timeout=TIMEOUT_S,
                    )
            except (requests.ConnectionError, requests.Timeout):
                if attempt == ATTEMPTS:
                    raise
            else:
                if response.status_code not in RETRY_STATUSES or attempt == ATTEMPTS:
                    return response
            time.sleep(2**attempt)
        raise AssertionError("unreachable")


def _checked(response: requests.Response) -> requests.Response:
    if response.status_code >= 400:
        print_error(response)
        sys.exit(1)
    return response


def print_error(response: requests.Response) -> None:
    """The API's error shape: {"detail": "...", "errors": [{"row", "field", "message"}]}."""
    try:
        body = response.json()
    except ValueError:
        body = {"detail": response.text[:500], "errors": []}
    print(f"HTTP {response.status_code}: {body.get('detail', '')}", file=sys.stderr)
    for error in body.get("errors", []):
        where = ", ".join(
            f"{name} {error[key]}" for name, key in (("row", "row"), ("column", "field"))
            if error.get(key) is not None
        )  # fmt: skip
        print(f"  {where + ': ' if where else ''}{error['message']}", file=sys.stderr)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--url", default="http://127.0.0.1:8000", help="service address")
    parser.add_argument("--key", default=os.environ.get("PT_API_KEY"), help="lab API key")
    parser.add_argument("--comparison", help="comparison code, e.g. IMU-2024-DEMO")
    parser.add_argument("--file", type=Path, help="results table to submit (CSV or XLSX)")
    parser.add_argument("--template", type=Path, help="save the results template here")
    parser.add_argument("--draft", action="store_true", help="save as a draft, do not submit")
    parser.add_argument(
        "--idempotency-key",
        help="send the submission with this key (default: a new UUID); the same key again "
        "answers the version already stored",
    )
    args = parser.parse_args(argv)
    if not args.key:
        parser.error("give --key or set PT_API_KEY")
    api = Api(args.url, args.key)

    for c in api.comparisons():
        deadline = c["submission_deadline"] or "no deadline"
        print(f"{c['code']:<20} {c['status']:<10} {deadline}  {c['title']}")
    if not args.comparison:
        return 0
    if args.template:
        fmt = "xlsx" if args.template.suffix.lower() == ".xlsx" else "csv"
        args.template.write_bytes(api.template(args.comparison, fmt))
        print(f"template saved to {args.template}")
    if not args.file:
        return 0
    key = args.idempotency_key or str(uuid.uuid4())
    print(f"Idempotency-Key: {key}")
    response = api.upload(args.comparison, args.file, submit=not args.draft, key=key)
    if response.status_code != 201:
        print_error(response)
        return 1
    s = response.json()
    print(f"stored: {s['participant']} version {s['version']}, {s['status']}, "
          f"{s['n_results']} results")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
