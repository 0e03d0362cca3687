"""The committed notebooks are the conversion of their percent-format sources in
``notebooks_src/`` (``minimanc exercises convert``): same cells, same text."""

from __future__ import annotations

from pathlib import Path

import nbformat
import pytest

from minimanc import exercises

ROOT = Path(__file__).resolve().parents[1]
SOURCES = sorted((ROOT / "notebooks_src").glob("*.py"))
FOLDER = {"tutorial": "tutorials", "solutions": "solutions"}


def _target(src: Path) -> Path:
    stem, kind = src.stem.rsplit("_", 1)
    return ROOT / FOLDER[kind] / f"{stem}.ipynb"


def test_every_tutorial_and_solution_has_a_source():
    targets = {_target(s) for s in SOURCES}
    for folder in FOLDER.values():
        for nb in (ROOT / folder).glob("*.ipynb"):
            assert nb in targets, f"{nb.name} in {folder}/ has no source in notebooks_src/"


@pytest.mark.parametrize("src", SOURCES, ids=lambda p: p.stem)
def test_notebook_matches_its_source(src):
    expected = exercises.cells_from_percent(src.read_text(), src.name)
    nb = nbformat.read(_target(src), as_version=4)
    got = [(c.cell_type, c.source) for c in nb.cells]
    want = [(c.cell_type, c.source) for c in expected]
    assert len(got) == len(want), f"{src.name}: {len(got)} cells, source has {len(want)}"
    for i, (g, w) in enumerate(zip(got, want)):
        assert g == w, (f"{_target(src).name} cell {i} differs from {src.name}: run "
                        f"`minimanc exercises convert {src.relative_to(ROOT)} ...`")
