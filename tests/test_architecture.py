"""The pure core stays free of Django and the packages import one way (docs/architecture.md §1,
§5): the import contracts pass on the tree and break when a module imports upwards."""

import ast
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

CORE = Path(__file__).resolve().parents[1] / "analysis" / "core"


def django_imports(path: Path) -> list[str]:
    tree = ast.parse(path.read_text(), filename=str(path))
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            names = [node.module or ""]
        else:
            continue
        found += [f"{path.name}:{node.lineno} {n}" for n in names if n.split(".")[0] == "django"]
    return found


def test_core_modules_exist():
    assert len(list(CORE.rglob("*.py"))) >= 2


def test_analysis_core_never_imports_django():
    offenders = [hit for p in sorted(CORE.rglob("*.py")) for hit in django_imports(p)]
    assert offenders == []


def test_detector_sees_django_imports(tmp_path):
    bad = tmp_path / "bad.py"
    bad.write_text("import numpy\nfrom django.db import models\ndef f():\n    import django\n")
    assert django_imports(bad) == ["bad.py:2 django.db", "bad.py:4 django"]


# --- import contracts (pyproject.toml [tool.importlinter], docs/architecture.md §5) ----------

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("config", "coordination", "analysis", "labs", "proficiency", "common")
LINT_IMPORTS = Path(sys.executable).parent / "lint-imports"


def lint_imports(cwd: Path, *contracts: str) -> subprocess.CompletedProcess[str]:
    """``lint-imports`` in ``cwd`` (its pyproject.toml), only ``contracts`` if given (ids)."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    chosen = [arg for c in contracts for arg in ("--contract", c)]
    return subprocess.run(
        [str(LINT_IMPORTS), "--no-cache", "--no-logo", *chosen],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )


def tree_copy(tmp_path: Path) -> Path:
    """The packages and pyproject.toml, copied: a probe planted there never touches the tree."""
    copy = tmp_path / "tree"
    for package in PACKAGES:
        shutil.copytree(
            ROOT / package, copy / package, ignore=shutil.ignore_patterns("__pycache__")
        )
    shutil.copy(ROOT / "pyproject.toml", copy / "pyproject.toml")
    return copy


def test_import_contracts_hold():
    done = lint_imports(ROOT)
    assert done.returncode == 0, done.stdout + done.stderr
    assert "7 kept, 0 broken" in done.stdout


@pytest.mark.parametrize(
    ("probe", "source", "contract"),
    [
        # the ground floor importing an app above it
        ("proficiency/_upward_probe.py", "import labs.models\n", "layers"),
        ("common/_upward_probe.py", "from proficiency import models\n", "layers"),
        # an import inside a function counts too
        ("labs/_upward_probe.py", "def f():\n    import analysis.services\n", "layers"),
        ("analysis/_upward_probe.py", "import coordination.views\n", "layers"),
        ("labs/_config_probe.py", "from config import settings\n", "project"),
        ("analysis/core/_probe.py", "import django.db\n", "pure-core"),
        ("analysis/core/_probe.py", "from analysis import models\n", "pure-core"),
        ("analysis/core/_probe.py", "from common import errors\n", "pure-core"),
        ("labs/importers/_probe.py", "import labs.models\n", "pure-importers"),
        # the point key the pure cores share stays pure
        ("common/points.py", "\nimport django.conf\n", "pure-ground"),
        ("common/sizes.py", "\nfrom common import jobs\n", "pure-ground"),
        ("common/numbers.py", "\nimport django.utils.formats\n", "pure-ground"),
        ("common/numbers.py", "\nfrom labs import models\n", "pure-ground"),
        ("labs/importers/_probe.py", "from analysis.core import robust\n", "pure-independent"),
        # appended to a service or selector: an edge imported from below
        ("labs/services.py", "\nimport labs.views\n", "services-below-edges"),
        (
            "analysis/selectors.py",
            "\ndef f():\n    from analysis import forms\n",
            "services-below-edges",
        ),
    ],
)
def test_import_contracts_fail_on_a_planted_import(tmp_path, probe, source, contract):
    copy = tree_copy(tmp_path)
    assert lint_imports(copy, contract).returncode == 0  # kept before the probe
    target = copy / probe
    target.write_text((target.read_text() if target.exists() else "") + source)
    done = lint_imports(copy, contract)
    assert done.returncode == 1, done.stdout + done.stderr
    assert "0 kept, 1 broken" in done.stdout
