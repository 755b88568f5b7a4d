"""The database connection is dropped in the middle of a bulk upload's ``COPY``
(``pg_terminate_backend`` from another connection, at a fixed row): the upload fails
with a clear error and nothing of it is stored."""

import psycopg
import pytest
from django.db import connection

from labs import services
from labs.models import Result, Submission
from tests.faults.conftest import DATABASE_URL
from tests.labs.test_upload_files import csv_file, grid, records  # noqa: F401

pytestmark = [pytest.mark.services, pytest.mark.django_db(transaction=True)]
KILL_AT = 1800  # of 3,600 rows


def terminate(pid: int) -> None:
    """Kill backend ``pid`` of the test database from another connection; wait until gone."""
    dsn = DATABASE_URL.rsplit("/", 1)[0] + "/" + connection.settings_dict["NAME"]
    with psycopg.connect(dsn, autocommit=True) as other:
        assert other.execute("select pg_terminate_backend(%s)", [pid]).fetchone() == (True,)
        for _ in range(100):
            alive = other.execute("select count(*) from pg_stat_activity where pid = %s", [pid])
            if alive.fetchone() == (0,):
                return
            other.execute("select pg_sleep(0.05)")
    pytest.fail(f"backend {pid} still alive")


class KilledMidway(list):
    """The rows of the COPY; the connection's backend is terminated when row KILL_AT is read."""

    def __iter__(self):
        for i, row in enumerate(list.__iter__(self)):
            if i == KILL_AT:
                terminate(connection.connection.info.backend_pid)
            yield row


def test_connection_dropped_mid_copy_stores_nothing(grid, monkeypatch):  # noqa: F811
    participant, user = grid
    data = csv_file(records())
    copied: list[int] = []
    original = services.results_insert

    def insert(values):
        copied.append(len(values))
        return original(KilledMidway(values))

    monkeypatch.setattr(services, "results_insert", insert)
    with pytest.raises(psycopg.OperationalError, match=r"terminat|server closed the connection"):
        services.submission_from_file(
            participant=participant, data=data, filename="r.csv", user=user, submit=True
        )
    assert copied == [3600]  # the COPY was under way when the connection went
    connection.close()  # the next query opens a new connection
    assert not Submission.objects.filter(participant=participant).exists()
    assert not Result.objects.filter(submission__participant=participant).exists()
    # and the same upload goes through once the database is back
    monkeypatch.setattr(services, "results_insert", original)
    done = services.submission_from_file(
        participant=participant, data=data, filename="r.csv", user=user, submit=True
    )
    assert (done.version, done.status, done.results.count()) == (1, "submitted", 3600)
