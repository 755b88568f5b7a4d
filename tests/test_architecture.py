"""The pure core stays free of Django (docs/architecture.md §1: the arrows point one way)."""

import ast
from pathlib import Path

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
