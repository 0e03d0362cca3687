"""Chapter 0 — solutions → exercises: the student version of each solutions notebook.

:func:`make_exercise` turns every solution region into
``raise NotImplementedError("Exercise <id>: <title>")``, every model answer of a
written-answer cell into ``YOUR ANSWER HERE``, removes hidden tests,
clears outputs and tags the cells that will raise; :func:`build` regenerates
``exercises/`` from ``solutions/`` (or, with ``check``, lists what is stale).
"""

from __future__ import annotations

import copy
from pathlib import Path

import nbformat

from minimanc.exercises.markers import (
    META_KEY,
    RAISES_TAG,
    assignment_name,
    cell_source,
    grade_id,
    is_answer_cell,
    is_grade_cell,
    is_solution_cell,
    source_fingerprint,
    strip_hidden,
    stub_answer,
    stub_solution,
    validate,
)

__all__ = [
    "build",
    "make_exercise",
]

# ----------------------------------------------------------------------------- build
def make_exercise(nb, name: str):
    """The student version of a solutions notebook (a new notebook object)."""
    validate(nb, name)
    out = copy.deepcopy(nb)
    out.metadata[META_KEY] = {
        "assignment": assignment_name(nb, name),
        "source_sha256": source_fingerprint(nb),
    }
    for index, cell in enumerate(out.cells):
        where = f"{name}: cell {index}"
        if is_answer_cell(cell):
            cell.source = stub_answer(cell_source(cell), where)
        if cell.cell_type != "code":
            continue
        cell.outputs = []
        cell.execution_count = None
        tags = [t for t in cell.metadata.get("tags", []) if t != RAISES_TAG]
        raises = False
        if is_solution_cell(cell):
            title = cell.metadata.get("minimanc", {}).get("title", "")
            cell.source, raises = stub_solution(cell_source(cell), grade_id(cell), title, where)
        if is_grade_cell(cell):
            cell.source = strip_hidden(cell_source(cell), where)
            raises = True
        if raises:
            tags.append(RAISES_TAG)
        if tags:
            cell.metadata["tags"] = tags
        else:
            cell.metadata.pop("tags", None)
    return out


def _dump(nb) -> str:
    return nbformat.writes(nb) + "\n"


def build(solutions: Path, exercises: Path, check: bool = False) -> list[str]:
    """Regenerate ``exercises/`` from ``solutions/``.

    With ``check`` nothing is written; returns the names of notebooks that are
    missing or out of date (empty list: in sync). Without it, returns the names
    written.
    """
    solutions, exercises = Path(solutions), Path(exercises)
    if not solutions.is_dir():
        raise FileNotFoundError(f"no solutions folder at {solutions}")
    stale = []
    expected = set()
    for path in sorted(solutions.glob("*.ipynb")):
        expected.add(path.name)
        nb = nbformat.read(path, as_version=4)
        text = _dump(make_exercise(nb, path.name))
        target = exercises / path.name
        current = target.read_text() if target.exists() else None
        if current != text:
            stale.append(path.name)
            if not check:
                exercises.mkdir(parents=True, exist_ok=True)
                target.write_text(text)
    for path in sorted(exercises.glob("*.ipynb")) if exercises.is_dir() else []:
        if path.name not in expected:
            stale.append(f"{path.name} (no solution notebook)")
    return stale
