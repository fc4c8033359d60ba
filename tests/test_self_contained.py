"""The repository stands on its own: no test, notebook, benchmark or package file reads outside it.

Two checks: a static scan of the sources for paths that climb out of the repository, and the runtime audit hook
of ``conftest.py`` (shown here to record an open beside the repository and to ignore one inside it).
"""

from __future__ import annotations

import re
from pathlib import Path

import conftest
import pytest
from conftest import REPO

# This file is left out: its examples of paths that climb out are what the scan must find.
SCANNED = sorted(
    p
    for folder in ("furuta_drake", "tests", "notebooks", "benchmarks")
    for p in (REPO / folder).rglob("*")
    if p.suffix in (".py", ".yaml", ".yml") and p.is_file() and p != Path(__file__).resolve()
)
BESIDE = str(REPO.parent).rstrip("/") + "/"  # the repository's parent, wherever it was cloned
# What climbs out of the repository from any of its files: a relative parent path, three or more parent steps
# (a package or test file is at most two levels below the repository's root), a sibling folder called shared, or
# an absolute path into the repository's parent directory.
CLIMBS = [
    (re.compile(r"\.\./|\.\.\\"), "a relative path to a parent directory"),
    (re.compile(r"(\.parent){3}|\.parents\[[2-9]\]|\.parents\[1\]\.parent"), "three or more parent steps"),
    (re.compile(r"""["'/]shared["'/]"""), "a folder called shared"),
    *([(re.compile(re.escape(BESIDE)), "an absolute path beside the repository")] if BESIDE != "/" else []),
]


def climbs_out(text: str) -> list[tuple[int, str, str]]:
    """(line number, line, why) of every line of ``text`` that names a path outside the repository."""
    return [
        (number, line.strip(), why)
        for number, line in enumerate(text.splitlines(), 1)
        for pattern, why in CLIMBS
        if pattern.search(line)
    ]


def test_the_scan_covers_every_kind_of_source():
    folders = {p.relative_to(REPO).parts[0] for p in SCANNED}
    assert folders == {"furuta_drake", "tests", "notebooks", "benchmarks"}
    assert REPO / "tests" / "conftest.py" in SCANNED and REPO / "furuta_drake" / "data.py" in SCANNED


@pytest.mark.parametrize(
    "line",
    [
        'DATA = Path(furuta_drake.__file__).resolve().parents[1].parent / "beside" / "data"',
        'QUBE_DATA = HERE.parent.parent.parent / "data"',
        'rig = load_rig("../beside/data/rig.yaml")',
        f"text = open('{BESIDE}beside/paper/notes.txt').read()",
        "root = Path(__file__).parents[3]",
    ],
)
def test_the_scan_finds_a_path_out_of_the_repository(line):
    assert climbs_out(f"import x\n{line}\n")[0][0] == 2


@pytest.mark.parametrize(
    "line",
    [
        "REPO = Path(__file__).resolve().parent.parent",
        'MODELS_DIR = Path(__file__).resolve().parent.parent / "models"',
        'shared_by = "the CLI and the notebooks"',
    ],
)
def test_the_scan_passes_paths_inside_the_repository(line):
    assert climbs_out(line) == []


def test_no_source_names_a_path_outside_the_repository():
    found = [
        f"{path.relative_to(REPO)}:{number}: {why}: {line}"
        for path in SCANNED
        for number, line, why in climbs_out(path.read_text())
    ]
    assert found == [], "\n".join(found)


def test_the_audit_hook_records_a_read_beside_the_repository_only(tmp_path):
    probe = REPO.parent / f".{REPO.name}-outside-read-probe"
    assert not probe.exists()
    before = len(conftest.OUTSIDE_READS)
    with pytest.raises(FileNotFoundError):
        open(probe)
    (REPO / "README.md").read_text()
    (tmp_path / "inside.txt").write_text("x")
    recorded = conftest.OUTSIDE_READS[before:]
    del conftest.OUTSIDE_READS[before:]  # the probe is this test's own doing, not a read to report
    assert recorded == [str(probe)]


DOCUMENTS = sorted(
    {REPO / "README.md"}
    | {
        p
        for folder in ("docs", "data", "tests", "notebooks", "benchmarks", "furuta_drake")
        for p in (REPO / folder).rglob("*.md")
    }
)


def test_no_document_points_outside_the_repository():
    """README, docs/, the data's and the corpus' READMEs name only files of the repository: no parent path and
    none of the project's private notes (the specification, the paper notes, the shared folder)."""
    outside = re.compile(r"\.\./|\bshared/|\bspec/|NOTES\.md")
    assert REPO / "docs" / "paper.md" in DOCUMENTS and REPO / "data" / "qube-servo2-real" / "README.md" in DOCUMENTS
    found = [
        f"{path.relative_to(REPO)}:{number}: {line.strip()}"
        for path in DOCUMENTS
        for number, line in enumerate(path.read_text().splitlines(), 1)
        if outside.search(line)
    ]
    assert found == [], "\n".join(found)
