"""Chapter 0 — the markers and metadata of a graded notebook: regions, stubs, validation.

A solution region sits between ``### BEGIN SOLUTION`` and ``### END SOLUTION``
in a solution cell; hidden tests between ``### BEGIN HIDDEN TESTS`` and
``### END HIDDEN TESTS`` in a grade cell (nbgrader's conventions). A written
answer graded by hand is a markdown *answer cell* (nbgrader's manually graded
answer: ``solution`` and ``grade`` true, ``task`` false, ``points``); its model
answer sits between the solution markers and becomes ``YOUR ANSWER HERE``.
:func:`validate` checks a solutions notebook, :func:`stub_solution`,
:func:`stub_answer` and :func:`strip_hidden` rewrite one cell,
:func:`source_fingerprint` hashes what grading takes from it.
"""

from __future__ import annotations

import hashlib
import json
import re
from pathlib import Path

__all__ = [
    "ANSWER_PLACEHOLDER",
    "BEGIN_HIDDEN",
    "BEGIN_SOLUTION",
    "END_HIDDEN",
    "END_SOLUTION",
    "META_KEY",
    "NotebookFormatError",
    "RAISES_TAG",
    "assignment_name",
    "cell_source",
    "answer_written",
    "grade_id",
    "is_answer_cell",
    "is_grade_cell",
    "is_solution_cell",
    "nbgrader_metadata",
    "source_fingerprint",
    "strip_hidden",
    "stub_answer",
    "stub_solution",
    "validate",
]

BEGIN_SOLUTION = "### BEGIN SOLUTION"
END_SOLUTION = "### END SOLUTION"
BEGIN_HIDDEN = "### BEGIN HIDDEN TESTS"
END_HIDDEN = "### END HIDDEN TESTS"
RAISES_TAG = "raises-exception"
ANSWER_PLACEHOLDER = "YOUR ANSWER HERE"
"""What replaces a written answer's model answer in the student's notebook (nbgrader's text)."""
META_KEY = "minimanc"
"""Key of the notebook- and cell-level metadata this module writes."""
_DOTTED = re.compile(r"^[A-Za-z_]\w*(\.[A-Za-z_]\w*)+$")


class NotebookFormatError(ValueError):
    """A graded notebook breaks the marker or metadata rules."""


# --------------------------------------------------------------------------- cells
def nbgrader_metadata(cell) -> dict:
    """The cell's ``nbgrader`` metadata (an empty dict when it has none)."""
    return cell.get("metadata", {}).get("nbgrader", {}) or {}


def is_grade_cell(cell) -> bool:
    """True for a code cell whose tests earn points."""
    return cell.get("cell_type") == "code" and bool(nbgrader_metadata(cell).get("grade"))


def is_solution_cell(cell) -> bool:
    """True for a code cell with a solution region to hide."""
    return cell.get("cell_type") == "code" and bool(nbgrader_metadata(cell).get("solution"))


def is_answer_cell(cell) -> bool:
    """True for a written answer graded by hand: a markdown cell that is both
    solution and grade (nbgrader's manually graded answer)."""
    meta = nbgrader_metadata(cell)
    return (cell.get("cell_type") == "markdown" and bool(meta.get("solution"))
            and bool(meta.get("grade")))


def grade_id(cell) -> str | None:
    """The cell's ``grade_id`` or None."""
    return nbgrader_metadata(cell).get("grade_id")


def cell_source(cell) -> str:
    """The cell's source as one string (nbformat may store a list of lines)."""
    src = cell.get("source", "")
    return "".join(src) if isinstance(src, list) else src


def _regions(lines: list[str], begin: str, end: str, where: str) -> list[tuple[int, int]]:
    """(start, stop) line indices of each begin/end region; refuses bad nesting."""
    regions, start = [], None
    for i, line in enumerate(lines):
        stripped = line.strip()
        if stripped.startswith(begin):
            if start is not None:
                raise NotebookFormatError(f"{where}: nested '{begin}' at line {i + 1}")
            start = i
        elif stripped.startswith(end):
            if start is None:
                raise NotebookFormatError(f"{where}: '{end}' at line {i + 1} without '{begin}'")
            regions.append((start, i))
            start = None
    if start is not None:
        raise NotebookFormatError(f"{where}: unclosed '{begin}' at line {start + 1}")
    return regions


def _check_markers(lines: list[str], where: str) -> None:
    """Refuse unclosed, nested or mismatched solution / hidden-test markers."""
    pairs = {BEGIN_SOLUTION: END_SOLUTION, BEGIN_HIDDEN: END_HIDDEN}
    ends = {v: k for k, v in pairs.items()}
    open_marker, open_line = None, 0
    for i, line in enumerate(lines, start=1):
        stripped = line.strip()
        begin = next((b for b in pairs if stripped.startswith(b)), None)
        end = next((e for e in ends if stripped.startswith(e)), None)
        if begin:
            if open_marker:
                raise NotebookFormatError(
                    f"{where}: nested '{begin}' at line {i} inside '{open_marker}' "
                    f"(line {open_line})"
                )
            open_marker, open_line = begin, i
        elif end:
            if open_marker is None:
                raise NotebookFormatError(f"{where}: '{end}' at line {i} without '{ends[end]}'")
            if pairs[open_marker] != end:
                raise NotebookFormatError(
                    f"{where}: mismatched '{end}' at line {i} closes '{open_marker}' "
                    f"(line {open_line})"
                )
            open_marker = None
    if open_marker:
        raise NotebookFormatError(f"{where}: unclosed '{open_marker}' at line {open_line}")


def stub_solution(source: str, exercise: str, title: str, where: str) -> tuple[str, bool]:
    """Replace each solution region by a ``NotImplementedError`` naming the exercise.

    Returns the new source and whether a region sat at top level (so the cell
    itself raises when run).
    """
    lines = source.split("\n")
    regions = _regions(lines, BEGIN_SOLUTION, END_SOLUTION, where)
    message = f"Exercise {exercise}: {title}" if title else f"Exercise {exercise}"
    out, top_level, last = [], False, 0
    for start, stop in regions:
        out.extend(lines[last:start])
        indent = lines[start][: len(lines[start]) - len(lines[start].lstrip())]
        top_level = top_level or indent == ""
        out.append(f"{indent}raise NotImplementedError({message!r})")
        last = stop + 1
    out.extend(lines[last:])
    return "\n".join(out), top_level


def stub_answer(source: str, where: str) -> str:
    """Replace each model-answer region (markers included) of an answer cell by
    ``YOUR ANSWER HERE``."""
    lines = source.split("\n")
    out, last = [], 0
    for start, stop in _regions(lines, BEGIN_SOLUTION, END_SOLUTION, where):
        out.extend(lines[last:start])
        out.append(ANSWER_PLACEHOLDER)
        last = stop + 1
    out.extend(lines[last:])
    return "\n".join(out)


def answer_written(source: str, stub: str) -> bool:
    """True when the student wrote something into an answer cell: its text differs
    from the stub (whitespace aside) and is more than ``YOUR ANSWER HERE``."""
    text = " ".join(source.split())
    return text != " ".join(stub.split()) and bool(text.replace(ANSWER_PLACEHOLDER, "").strip())


def strip_hidden(source: str, where: str) -> str:
    """Remove hidden-test regions (markers included)."""
    lines = source.split("\n")
    keep = [True] * len(lines)
    for start, stop in _regions(lines, BEGIN_HIDDEN, END_HIDDEN, where):
        for i in range(start, stop + 1):
            keep[i] = False
    return "\n".join(line for line, k in zip(lines, keep) if k)


# ------------------------------------------------------------------------- validation
def validate(nb, name: str) -> list[str]:
    """Check markers and metadata of a solutions notebook; return its exercise ids."""
    seen: dict[str, int] = {}
    exercises = []
    for index, cell in enumerate(nb.cells):
        where = f"{name}: cell {index}"
        src = cell_source(cell)
        lines = src.split("\n")
        _check_markers(lines, where)
        has_solution = bool(_regions(lines, BEGIN_SOLUTION, END_SOLUTION, where))
        has_hidden = bool(_regions(lines, BEGIN_HIDDEN, END_HIDDEN, where))
        gid = grade_id(cell)
        if cell.cell_type != "code" and not is_answer_cell(cell):
            meta = nbgrader_metadata(cell)
            if meta.get("solution") or meta.get("grade"):
                raise NotebookFormatError(
                    f"{where}: a {cell.cell_type} cell marked solution or grade must be an "
                    "answer cell (markdown, solution and grade both true)"
                )
            if has_solution or has_hidden:
                raise NotebookFormatError(
                    f"{where}: markers are only allowed in code cells and answer cells"
                )
        if is_answer_cell(cell):
            _check_answer(cell, gid, has_solution, has_hidden, where)
            if gid in seen:
                raise NotebookFormatError(
                    f"{where}: duplicate grade_id {gid!r} (first in cell {seen[gid]})"
                )
            seen[gid] = index
            continue
        if has_solution and not is_solution_cell(cell):
            raise NotebookFormatError(f"{where}: solution markers in a cell not marked solution")
        if has_hidden and not is_grade_cell(cell):
            raise NotebookFormatError(f"{where}: hidden tests in a cell that is not a grade cell")
        if is_solution_cell(cell) and not has_solution:
            raise NotebookFormatError(f"{where}: solution cell without '{BEGIN_SOLUTION}'")
        if is_solution_cell(cell) or is_grade_cell(cell):
            if not gid:
                raise NotebookFormatError(f"{where}: graded cell without a grade_id")
            if gid in seen:
                raise NotebookFormatError(
                    f"{where}: duplicate grade_id {gid!r} (first in cell {seen[gid]})"
                )
            seen[gid] = index
        if is_grade_cell(cell):
            points = nbgrader_metadata(cell).get("points")
            if not isinstance(points, int | float) or points <= 0:
                raise NotebookFormatError(f"{where}: grade cell {gid!r} needs positive points")
        if is_solution_cell(cell):
            exercises.append(gid)
            forbids = cell.metadata.get(META_KEY, {}).get("forbids", [])
            bad = [f for f in forbids if not isinstance(f, str) or not _DOTTED.match(f)]
            if not isinstance(forbids, list) or bad:
                raise NotebookFormatError(
                    f"{where}: forbids must list dotted names like minimanc.dmp.classify, "
                    f"got {bad or forbids!r}"
                )
    return exercises


def _check_answer(cell, gid, has_solution: bool, has_hidden: bool, where: str) -> None:
    """An answer cell: a grade_id, positive points, a model answer, no hidden tests."""
    meta = nbgrader_metadata(cell)
    if not gid:
        raise NotebookFormatError(f"{where}: answer cell without a grade_id")
    if meta.get("task"):
        raise NotebookFormatError(f"{where}: answer cell {gid!r} cannot be a task (task: false)")
    points = meta.get("points")
    if isinstance(points, bool) or not isinstance(points, int | float) or points <= 0:
        raise NotebookFormatError(f"{where}: answer cell {gid!r} needs positive points")
    if not has_solution:
        raise NotebookFormatError(
            f"{where}: answer cell {gid!r} without a model answer between "
            f"'{BEGIN_SOLUTION}' and '{END_SOLUTION}'"
        )
    if has_hidden:
        raise NotebookFormatError(f"{where}: answer cell {gid!r} cannot hold hidden tests")


def source_fingerprint(nb) -> str:
    """sha256 of what grading takes from a solutions notebook: the grade cells
    (id, points, source), each exercise's forbidden functions and the answer
    cells (id, points)."""
    items = []
    for cell in nb.cells:
        if is_grade_cell(cell):
            items.append(["grade", grade_id(cell), nbgrader_metadata(cell).get("points"),
                          cell_source(cell)])
        elif is_solution_cell(cell):
            items.append(["forbids", grade_id(cell),
                          cell.metadata.get(META_KEY, {}).get("forbids", [])])
        elif is_answer_cell(cell):
            items.append(["answer", grade_id(cell), nbgrader_metadata(cell).get("points")])
    return hashlib.sha256(json.dumps(items, sort_keys=True).encode()).hexdigest()


def assignment_name(nb, name: str) -> str:
    """The assignment id of a solutions notebook: its metadata, else its file stem."""
    meta = nb.get("metadata", {}).get(META_KEY, {})
    value = meta.get("assignment") if isinstance(meta, dict) else None
    return value if isinstance(value, str) and value else Path(name).stem
