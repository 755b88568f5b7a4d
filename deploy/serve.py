#!/usr/bin/env python3
"""``make serve``: the production processes on one machine, supervised together.

Prepares (``migrate``, ``collectstatic``, ``check --deploy``), then runs gunicorn,
one Celery worker and Celery beat, prefixes their output with their name, and
stops all three (SIGTERM, then SIGKILL after a grace period) on Ctrl-C, on
SIGTERM, or as soon as one of them exits. The exit status is non-zero when a
process died on its own.

Configuration comes from the environment (README, "Configuration"), or from a
file named by ``ENV_FILE`` (see ``deploy/env.example``). ``DATABASE_URL`` and
``CELERY_BROKER_URL`` are required: production mode never falls back to SQLite
or to eager tasks. For a machine with systemd, ``deploy/systemd/`` runs the
same three processes as units.
"""

from __future__ import annotations

import os
import selectors
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
BIN = Path(sys.executable).parent
GRACE_SECONDS = 20
REQUIRED = ("SECRET_KEY", "DATABASE_URL", "CELERY_BROKER_URL")


def environment() -> dict[str, str]:
    """The processes' environment: ``ENV_FILE`` read in, production defaults, checked."""
    env = dict(os.environ)
    if env.get("ENV_FILE"):
        env.update({k: v for k, v in read_env_file(Path(env["ENV_FILE"])).items() if k not in env})
    env.setdefault("DEBUG", "false")
    env.setdefault("DJANGO_SETTINGS_MODULE", "config.settings")
    env["PYTHONUNBUFFERED"] = "1"
    missing = [name for name in REQUIRED if not env.get(name)]
    if missing:
        sys.exit(
            f"make serve: set {', '.join(missing)} (environment or ENV_FILE=path); "
            "see deploy/env.example."
        )
    return env


def read_env_file(path: Path) -> dict[str, str]:
    """``NAME=value`` lines; blank lines and ``#`` comments ignored, optional quotes removed."""
    values = {}
    for line in path.read_text().splitlines():
        line = line.strip()
        if line and not line.startswith("#") and "=" in line:
            name, value = line.split("=", 1)
            values[name.strip().removeprefix("export ").strip()] = value.strip().strip("'\"")
    return values


def commands(state_dir: str) -> dict[str, list[str]]:
    python = sys.executable
    return {
        "web": [str(BIN / "gunicorn"), "-c", str(ROOT / "deploy" / "gunicorn.conf.py")],
        "worker": [python, "-m", "celery", "-A", "config", "worker", "-l", "INFO"],
        "beat": [
            python, "-m", "celery", "-A", "config", "beat", "-l", "INFO",
            "--schedule", os.path.join(state_dir, "celerybeat-schedule"),
        ],
    }  # fmt: skip


def prepare(env: dict[str, str]) -> None:
    manage = [sys.executable, str(ROOT / "manage.py")]
    for step in (["migrate", "--noinput"], ["collectstatic", "--noinput", "-v", "0"],
                 ["check", "--deploy", "--fail-level", "ERROR"]):  # fmt: skip
        print(f"serve | manage.py {' '.join(step)}", flush=True)
        subprocess.run([*manage, *step], cwd=ROOT, env=env, check=True)


def start(env: dict[str, str], state_dir: str) -> dict[str, subprocess.Popen[bytes]]:
    procs = {}
    for name, argv in commands(state_dir).items():
        procs[name] = subprocess.Popen(
            argv, cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
            start_new_session=True,  # Ctrl-C reaches us only; we stop the children in order
        )  # fmt: skip
        print(f"serve | started {name} (pid {procs[name].pid}): {' '.join(argv)}", flush=True)
    return procs


def pump(procs: dict[str, subprocess.Popen[bytes]], stopping: list[bool]) -> str | None:
    """Copy output line by line until one process exits or a stop is asked; who exited."""
    sel = selectors.DefaultSelector()
    width = max(map(len, procs))
    for name, proc in procs.items():
        assert proc.stdout is not None
        sel.register(proc.stdout, selectors.EVENT_READ, name)
    while not stopping[0]:
        for key, _ in sel.select(timeout=0.5):
            line = key.fileobj.readline()  # type: ignore[union-attr]
            if line:
                sys.stdout.write(f"{key.data:<{width}} | {line.decode(errors='replace')}")
                sys.stdout.flush()
        for name, proc in procs.items():
            if proc.poll() is not None:
                return name
    return None


def stop(procs: dict[str, subprocess.Popen[bytes]]) -> None:
    for proc in procs.values():
        if proc.poll() is None:
            proc.send_signal(signal.SIGTERM)  # warm shutdown: gunicorn and Celery finish work
    deadline = time.monotonic() + GRACE_SECONDS
    for name, proc in procs.items():
        try:
            proc.wait(timeout=max(deadline - time.monotonic(), 0.1))
        except subprocess.TimeoutExpired:
            print(f"serve | {name} did not stop in {GRACE_SECONDS} s: killed", flush=True)
            proc.kill()
            proc.wait()


def main() -> int:
    env = environment()
    prepare(env)
    stopping = [False]

    def ask_stop(signum: int, frame: object) -> None:
        stopping[0] = True

    signal.signal(signal.SIGINT, ask_stop)
    signal.signal(signal.SIGTERM, ask_stop)
    with tempfile.TemporaryDirectory(prefix="pt-serve-") as state_dir:
        procs = start(env, state_dir)
        exited = pump(procs, stopping)
        if exited:
            print(f"serve | {exited} exited with {procs[exited].returncode}: stopping", flush=True)
        else:
            print("serve | stopping", flush=True)
        stop(procs)
        drain(procs)
    return 1 if exited else 0


def drain(procs: dict[str, subprocess.Popen[bytes]]) -> None:
    """What the processes wrote while shutting down, then their exit statuses."""
    width = max(map(len, procs))
    for name, proc in procs.items():
        assert proc.stdout is not None
        for line in proc.stdout.read().decode(errors="replace").splitlines():
            print(f"{name:<{width}} | {line}")
    codes = ", ".join(f"{name} {proc.returncode}" for name, proc in procs.items())
    print(f"serve | stopped ({codes})", flush=True)


if __name__ == "__main__":
    sys.exit(main())
