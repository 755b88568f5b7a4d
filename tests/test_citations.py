"""Every document the code cites is in the tree (docs/README.md): a citation such as
"docs/domain.md §5.3" names a file under docs/ and a numbered heading in it; the code
cites no issue numbers and no file outside the repository."""

import re
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CITATION = re.compile(r"docs/([a-z]+\.md)(?: §(\d+(?:\.\d+)?))?")
SECTION_CITED_ALONE = re.compile(
    r"docs/([a-z]+\.md) §\d+(?:\.\d+)?((?:(?:, | and |–)§?\d+(?:\.\d+)?)+)"
)
ISSUE_NUMBER = re.compile(r"\bissues? #?\d+\b", re.IGNORECASE)
OUTSIDE = re.compile(
    r"(?<![\w/])(formats|style)\.md|\.\./shared|(?<![\w/])spec/domain\.md|\"shared\" / \"spec\""
)


def tracked_text_files() -> list[Path]:
    out = subprocess.run(
        ["git", "ls-files", "*.py", "*.html", "*.txt", "*.toml", "*.cfg", "Makefile", ".ci/*"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        check=True,
    ).stdout.split()
    return [ROOT / name for name in out if (ROOT / name).is_file()]


def headings(doc: str) -> set[str]:
    text = (ROOT / "docs" / doc).read_text()
    return set(re.findall(r"^#{2,3} (\d+(?:\.\d+)?)[. ]", text, re.MULTILINE))


def unresolved(text: str, where: str) -> list[str]:
    bad = []
    for match in CITATION.finditer(text):
        doc, section = match.groups()
        if not (ROOT / "docs" / doc).is_file():
            bad.append(f"{where}: {match.group(0)} (no such document)")
        elif section and section not in headings(doc):
            bad.append(f"{where}: {match.group(0)} (no such section)")
    for match in SECTION_CITED_ALONE.finditer(text):
        for section in re.findall(r"\d+(?:\.\d+)?", match.group(2)):
            if section not in headings(match.group(1)):
                bad.append(f"{where}: {match.group(1)} §{section} (no such section)")
    return bad


def test_every_cited_document_and_section_exists():
    files = tracked_text_files()
    assert len(files) > 200
    mine = Path(__file__).name  # its own examples of bad citations
    bad = [hit for p in files if p.name != mine for hit in unresolved(p.read_text(), p.name)]
    assert bad == []


def test_no_issue_numbers_and_no_files_outside_the_tree():
    hits = []
    for path in tracked_text_files():
        if path.name == Path(__file__).name:
            continue
        for lineno, line in enumerate(path.read_text().splitlines(), 1):
            if ISSUE_NUMBER.search(line) or OUTSIDE.search(line):
                hits.append(f"{path.relative_to(ROOT)}:{lineno}: {line.strip()}")
    assert hits == []


def test_the_checks_see_bad_citations():
    assert unresolved("see docs/domain.md §5.3 and docs/interfaces.md §1", "x") == []
    assert unresolved("see docs/domain.md §5.42", "x") == [
        "x: docs/domain.md §5.42 (no such section)"
    ]
    assert unresolved("docs/formats.md §1", "x") == ["x: docs/formats.md §1 (no such document)"]
    assert unresolved("docs/interfaces.md §2, §9", "x") == ["x: interfaces.md §9 (no such section)"]
    assert ISSUE_NUMBER.search("(issue 7 item 8)") and ISSUE_NUMBER.search("issue #9")
    assert OUTSIDE.search("see formats.md §1") and OUTSIDE.search("../shared/spec/x")
    assert OUTSIDE.search('Path(x).parent / "shared" / "spec" / "reference-data"')
    assert not OUTSIDE.search("docs/domain.md §3")


# --- what a reader sees cites no document of ours ---------------------------------------------

APPS = ("common", "proficiency", "labs", "analysis", "coordination", "config")
#: a citation of our docs in text a person reads; a standard's clause (ISO 5725-2 §7) is fine
OURS = re.compile(r"docs/[a-z]+\.md|[a-z]+\.md §|(?<!ISO )(?<!\d )(?<!\d\d )§")
TEMPLATE_COMMENT = re.compile(r"\{#.*?#\}|\{% comment %\}.*?\{% endcomment %\}", re.DOTALL)


def _shown_strings(source: str) -> list[tuple[int, str]]:
    """The string constants of a module that are not docstrings: notes, messages, help
    texts, report text (f-strings' literal parts included)."""
    import ast

    tree = ast.parse(source)
    docs = {
        id(node.value)
        for node in ast.walk(tree)
        if isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant)
    }
    return [
        (node.lineno, node.value)
        for node in ast.walk(tree)
        if isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in docs
    ]


def test_no_reader_is_sent_to_our_docs():
    """Run notes, messages, help texts, report text and pages say what they mean in words:
    a reader has no docs/ (comments and docstrings keep their citations)."""
    hits = []
    for path in tracked_text_files():
        rel = path.relative_to(ROOT)
        if rel.parts[0] == "templates":
            text = TEMPLATE_COMMENT.sub("", path.read_text())
            hits += [f"{rel}: {m.group(0)}" for m in OURS.finditer(text)]
        elif rel.parts[0] in APPS and path.suffix == ".py" and "migrations" not in rel.parts:
            for line, value in _shown_strings(path.read_text()):
                hits += [f"{rel}:{line}: {value[:80]!r}" for _ in OURS.finditer(value)][:1]
    assert hits == []


def test_the_reader_check_sees_a_citation():
    assert OURS.search("its scores stand (docs/domain.md §14)")
    assert OURS.search("by least squares (§14)") and OURS.search("see interfaces.md §1")
    assert not OURS.search("ISO 5725-2 §7.3.4") and not OURS.search("ISO 13528:2022 §9")
    assert not OURS.search("/api/docs/")
    assert TEMPLATE_COMMENT.sub("", "a {# docs/domain.md §4 #} b") == "a  b"
