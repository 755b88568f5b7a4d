"""The lock files are in sync with the ranges: requirements.txt and requirements-dev.txt are
the human-edited ranges, requirements.lock and requirements-dev.lock (``make lock``, uv) pin
every package with its hashes, and ``make`` installs from the locks only. Editing a range
without running ``make lock`` fails here."""

import re
from pathlib import Path

import pytest
from packaging.requirements import Requirement
from packaging.utils import canonicalize_name
from packaging.version import Version

ROOT = Path(__file__).resolve().parents[1]
# What the locks are compiled for (Makefile: LOCK_PLATFORM).
LOCK_ENVIRONMENT = {
    "python_version": "3.11",
    "python_full_version": "3.11.0",
    "sys_platform": "linux",
    "platform_system": "Linux",
    "platform_machine": "x86_64",
    "os_name": "posix",
    "implementation_name": "cpython",
    "platform_python_implementation": "CPython",
}
PIN = re.compile(r"^([A-Za-z0-9][A-Za-z0-9._-]*)==([^\s\\;]+)")
# Ranges and their locks; a dev install gets everything in the runtime ranges too.
LOCKS = {
    "requirements.txt": "requirements.lock",
    "requirements-dev.txt": "requirements-dev.lock",
}


def ranges(name: str) -> list[Requirement]:
    """The requirements of a ranges file, following ``-r`` includes."""
    found = []
    for raw in (ROOT / name).read_text().splitlines():
        line = raw.split(" #", 1)[0].strip()
        if not line or line.startswith("#"):
            continue
        if line.startswith(("-r ", "--requirement ")):
            found += ranges(line.split(None, 1)[1])
            continue
        assert not line.startswith("-"), f"{name}: option {line!r} is not understood here"
        found.append(Requirement(line))
    return found


def pins(name: str) -> dict[str, Version]:
    found: dict[str, Version] = {}
    for line in (ROOT / name).read_text().splitlines():
        match = PIN.match(line)
        if match:
            found[canonicalize_name(match.group(1))] = Version(match.group(2))
    return found


def unhashed(name: str) -> list[str]:
    """Pins without a ``--hash`` (``pip install --require-hashes`` would refuse them)."""
    text = (ROOT / name).read_text()
    entries = re.split(r"\n(?=[A-Za-z0-9])", text)
    return [e.split()[0] for e in entries if PIN.match(e) and "--hash=sha256:" not in e]


@pytest.mark.parametrize(("ranges_file", "lock_file"), LOCKS.items())
def test_every_range_is_pinned_within_it(ranges_file, lock_file):
    locked = pins(lock_file)
    problems = []
    for req in ranges(ranges_file):
        if req.marker and not req.marker.evaluate(LOCK_ENVIRONMENT):
            continue
        version = locked.get(canonicalize_name(req.name))
        if version is None:
            problems.append(f"{req.name}: not in {lock_file}")
        elif not req.specifier.contains(version):
            problems.append(f"{req.name}: {lock_file} pins {version}, outside {req.specifier}")
    assert problems == [], f"run `make lock` after editing {ranges_file}"


@pytest.mark.parametrize("lock_file", LOCKS.values())
def test_every_pin_has_hashes(lock_file):
    assert pins(lock_file), f"{lock_file} pins nothing"
    assert unhashed(lock_file) == []


def test_dev_lock_pins_the_runtime_lock():
    """The dev environment (tests, CI) runs the versions production installs."""
    runtime, dev = pins("requirements.lock"), pins("requirements-dev.lock")
    differ = {n: (v, dev.get(n)) for n, v in runtime.items() if dev.get(n) != v}
    assert differ == {}, "run `make lock`"


@pytest.mark.parametrize("lock_file", LOCKS.values())
def test_no_torch(lock_file):
    """torch is no dependency of the service; a lock that pulls it is wrong."""
    assert {"torch", "torchvision"} & set(pins(lock_file)) == set()


def test_pin_parser():
    match = PIN.match("rl-accel==0.9.1 \\")
    assert match is not None and match.groups() == ("rl-accel", "0.9.1")
    assert PIN.match("    --hash=sha256:00") is None
    assert PIN.match("    # via -r requirements.txt") is None
