"""Chapter 0 — grading a notebook against the authoritative tests of its solutions notebook.

:func:`grade` executes a notebook and scores each grade cell against the grade
cells (hidden tests included) of ``solutions/<assignment>.ipynb``, never
against the notebook's own; while an exercise's grade cells run, the library
functions it ``forbids`` raise (:func:`minimanc.exercises.shadow`). Before any
student cell runs, the tools grade cells rely on are captured; before each grade
cell whatever student code replaced is restored and named on the grade cell's
row, and the grade cell runs against the captured tools with strict answer types
(:mod:`minimanc.exercises.integrity`).
"""

from __future__ import annotations

import ast
import copy
import json
import re
import secrets
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import nbformat

from minimanc.errors import UsageError
from minimanc.exercises.conversion import TIMEOUT_ENAME, notebook_client
from minimanc.exercises.integrity import defined_names, imported_names, read_names
from minimanc.exercises.markers import (
    BEGIN_HIDDEN,
    END_HIDDEN,
    META_KEY,
    NotebookFormatError,
    cell_source,
    grade_id,
    is_grade_cell,
    is_solution_cell,
    nbgrader_metadata,
    source_fingerprint,
    validate,
)

__all__ = [
    "DEFAULT_TIMEOUT",
    "GradeRefused",
    "GradeReport",
    "GradeRow",
    "assignment_of",
    "exercise_of_grade_cells",
    "find_source",
    "forbidden_functions",
    "grade",
    "instrument_grade_source",
    "read_notebook",
]

DEFAULT_TIMEOUT = 120


# ---------------------------------------------------------------------------- grading
class GradeRefused(UsageError):
    """The notebook cannot be graded: missing, unreadable, or no authoritative source."""


@dataclass
class GradeRow:
    """One grade cell's result; ``hidden`` is True when a hidden test failed."""

    grade_id: str
    points: float
    max_points: float
    message: str = ""
    hidden: bool = False
    tampered: list[str] = field(default_factory=list)


@dataclass
class GradeReport:
    """Points per grade cell, plus notes on what went wrong with the notebook."""

    notebook: str
    assignment: str = ""
    source: str = ""
    rows: list[GradeRow] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    @property
    def total(self) -> float:
        return sum(r.points for r in self.rows)

    @property
    def max_total(self) -> float:
        return sum(r.max_points for r in self.rows)

    def to_dict(self) -> dict:
        return {
            "notebook": self.notebook,
            "assignment": self.assignment,
            "source": self.source,
            "total": self.total,
            "max_total": self.max_total,
            "rows": [copy.deepcopy(r.__dict__) for r in self.rows],
            "notes": self.notes,
        }

    def format(self) -> str:
        width = max([len(r.grade_id) for r in self.rows] + [8])
        head = f"{self.notebook} (assignment {self.assignment})" if self.assignment else ""
        lines = [head or self.notebook]
        for r in self.rows:
            mark = "ok  " if r.points == r.max_points else "FAIL"
            tail = f"  {r.message}" if r.message else ""
            lines.append(f"  {mark} {r.grade_id:<{width}} {r.points:g}/{r.max_points:g}{tail}")
        lines.extend(f"  note: {n}" for n in self.notes)
        lines.append(f"  total {self.total:g}/{self.max_total:g}")
        return "\n".join(lines)


def _one_line(text: str, limit: int = 200) -> str:
    text = " ".join(str(text).split())
    return text if len(text) <= limit else text[: limit - 3] + "..."


def read_notebook(path: Path, what: str = "notebook"):
    """Read a notebook for grading, refusing anything that is not one.

    Raises :class:`GradeRefused` (one line, naming ``path``) for a missing file,
    a directory, a binary file, invalid JSON or JSON that is not a notebook.
    """
    path = Path(path)
    if not path.exists():
        raise GradeRefused(f"{what} {path}: no such file")
    if path.is_dir():
        raise GradeRefused(f"{what} {path} is a directory, not a notebook")
    try:
        text = path.read_bytes().decode("utf-8")
    except UnicodeDecodeError:
        raise GradeRefused(f"{what} {path} is not a notebook (a binary file)") from None
    except OSError as exc:
        raise GradeRefused(f"{what} {path}: cannot read: {exc.strerror or exc}") from None
    if "\x00" in text:
        raise GradeRefused(f"{what} {path} is not a notebook (a binary file)")
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise GradeRefused(
            f"{what} {path} is not valid JSON (line {exc.lineno}, column {exc.colno}: {exc.msg})"
        ) from None
    if not isinstance(data, dict) or not isinstance(data.get("cells"), list):
        raise GradeRefused(f"{what} {path} is JSON but not a Jupyter notebook (no cell list)")
    try:
        return nbformat.reads(text, as_version=4)
    except Exception as exc:  # noqa: BLE001 - any nbformat failure is a bad notebook
        raise GradeRefused(
            f"{what} {path} is not a readable notebook: {_one_line(exc)}"
        ) from None


_ASSIGNMENT = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")


def assignment_of(nb) -> str | None:
    """The assignment id that ``exercises build`` wrote into the notebook, or None."""
    meta = nb.get("metadata", {}).get(META_KEY, {})
    value = meta.get("assignment") if isinstance(meta, dict) else None
    return value if isinstance(value, str) and _ASSIGNMENT.match(value) else None


def find_source(path: Path, assignment: str, roots: Sequence[Path] = ()) -> Path | None:
    """The solutions notebook of ``assignment``: ``ROOT/solutions/<assignment>.ipynb``.

    ``roots`` (the course checkout first) are searched before the folder above
    the notebook at ``path``; the file name of ``path`` plays no part.
    """
    if not _ASSIGNMENT.match(assignment or ""):
        return None
    folders = [Path(r) for r in roots] + [Path(path).resolve().parent.parent]
    for folder in folders:
        candidate = folder / "solutions" / f"{assignment}.ipynb"
        if candidate.is_file():
            return candidate
    return None


def _first_error(cell) -> str | None:
    for output in cell.get("outputs", []):
        if output.get("output_type") == "error":
            value = _one_line(output.get("evalue", ""))
            return f"{output.get('ename', 'Error')}: {value}" if value else output.get("ename")
    return None


def _stdout(cell) -> str:
    return "".join(
        o.get("text", "") for o in cell.get("outputs", [])
        if o.get("output_type") == "stream" and o.get("name") == "stdout"
    )


def exercise_of_grade_cells(nb) -> dict[str, str]:
    """grade_id of each grade cell → id of the nearest solution cell before it."""
    out, current = {}, None
    for cell in nb.cells:
        if is_solution_cell(cell):
            current = grade_id(cell)
        elif is_grade_cell(cell) and grade_id(cell):
            out[grade_id(cell)] = current or grade_id(cell)
    return out


def forbidden_functions(nb) -> dict[str, list[str]]:
    """Exercise id → the library functions its solution cell declares ``forbids``."""
    return {
        grade_id(c): list(c.metadata.get(META_KEY, {}).get("forbids", []))
        for c in nb.cells if is_solution_cell(c)
    }


_PART = "_minimanc_grading_part"
_GUARD = "_minimanc_grading_guard"


def instrument_grade_source(source: str, nonce: str) -> tuple[str, bool]:
    """The grade cell to execute: it records whether a hidden test is running and
    prints ``nonce`` as its last act (so a swallowed exception does not pass).

    Returns the source and whether hidden regions could be labelled (the marker
    lines become assignments at their indentation; if that is not valid Python
    the cell runs unlabelled).
    """
    lines = source.split("\n")
    labelled = []
    for line in lines:
        stripped = line.strip()
        indent = line[: len(line) - len(line.lstrip())]
        if stripped.startswith(BEGIN_HIDDEN):
            labelled.append(f'{indent}{_PART} = "hidden"')
        elif stripped.startswith(END_HIDDEN):
            labelled.append(f'{indent}{_PART} = "visible"')
        else:
            labelled.append(line)
    head, tail = f'{_PART} = "visible"\n', f"\nprint({nonce!r})"
    candidate = head + "\n".join(labelled) + tail
    try:
        ast.parse(candidate)
        return candidate, True
    except SyntaxError:
        return head + source + tail, False


def _setup_source(targets: list[str], exercise: str) -> str:
    return (
        "import minimanc.exercises\n"
        f"{_GUARD} = minimanc.exercises.shadow({targets!r}, {exercise!r}, globals())"
    )


_INTEGRITY = "import minimanc.exercises.integrity as _minimanc_integrity\n"


def _capture_source(reference) -> str:
    """The first cell: capture the tools (the solutions notebook's imports) before
    any student cell runs."""
    plain = [cell_source(c) for c in reference.cells if c.cell_type == "code"
             and not is_grade_cell(c) and not is_solution_cell(c)]
    classes = [n for c in reference.cells if c.cell_type == "code" and not is_grade_cell(c)
               for n in defined_names(cell_source(c))[1]]
    return (_INTEGRITY + f"_minimanc_integrity.capture({imported_names(plain)!r}, "
            f"{sorted(set(classes))!r})\ndel _minimanc_integrity")


def _restore_source(token: str, read: list[str], answers: list[str]) -> str:
    return (_INTEGRITY + f"_minimanc_integrity.restore({token!r}, globals(), {read!r}, "
            f"{answers!r})\ndel _minimanc_integrity")


def _run_source(source: str, answers: list[str], gid: str) -> str:
    return (_INTEGRITY + f"_minimanc_integrity.run_grade({source!r}, globals(), {answers!r}, "
            f"{f'<grade cell {gid}>'!r})")


def _probe_source(nonce: str, token: str, guarded: bool) -> str:
    restore = f"    {_GUARD}.restore()\n" if guarded else "    pass\n"
    return (
        f"try:\n{restore}finally:\n"
        f"    {_INTEGRITY}"
        f"    _minimanc_integrity.check_after({token!r})\n"
        f"    print({nonce!r} + ':' + str(globals().get({_PART!r}, '?')))"
    )


@dataclass
class _Slot:
    """Where one expected grade cell sits in the notebook being executed, and the
    tokens its cells print (fresh for each grade cell, so a token seen in one
    cell's output cannot be replayed in another)."""

    check: int
    grade: int
    probe: int
    labelled: bool
    nonce: str
    before: str
    after: str


def _found(cell, token: str) -> list[str] | None:
    """The names printed after ``token`` by a restore/check call, None if absent.

    The last such line counts: a ``pre_run_cell`` callback of the student's, run
    before the restore removes it, may have printed a forged one earlier.
    """
    for line in reversed(_stdout(cell).splitlines()):
        if line.startswith(token + ":"):
            try:
                names = json.loads(line[len(token) + 1:])
            except json.JSONDecodeError:
                return None
            return [str(n) for n in names] if isinstance(names, list) else None
    return None


def _listing(names: list[str], limit: int = 6) -> str:
    more = f" and {len(names) - limit} more" if len(names) > limit else ""
    return ", ".join(names[:limit]) + more


def grade(
    path: Path,
    source: Path | None = None,
    timeout: int = DEFAULT_TIMEOUT,
    roots: Sequence[Path] = (),
) -> GradeReport:
    """Execute the notebook at ``path`` and score it against the authoritative tests.

    The tests always come from the solutions notebook (``source``, or
    ``solutions/<assignment>.ipynb`` found via :func:`find_source` from the
    assignment id in the notebook's metadata); the notebook's own grade cells are
    never trusted. Grade cells are matched by ``grade_id``: moved cells are fine;
    a deleted one (or one whose metadata was removed) scores 0 and is listed; a
    duplicated one is scored once. While an exercise's grade cells run, the
    library functions it ``forbids`` raise (see :func:`shadow`). A cell that runs
    longer than ``timeout`` seconds is interrupted; a crashed kernel leaves the
    remaining cells unscored.

    Raises :class:`GradeRefused` when the notebook cannot be read or its source
    cannot be identified; otherwise never raises for what the notebook does.
    """
    path = Path(path)
    student = read_notebook(path)
    assignment = assignment_of(student)
    if source is not None:
        source = Path(source)
        reference_nb = read_notebook(source, "--source")
        ref_assignment = assignment_of(reference_nb) or source.stem
        if assignment and assignment != ref_assignment:
            raise GradeRefused(
                f"{path.name} is assignment {assignment!r} but --source {source} is "
                f"{ref_assignment!r}"
            )
        assignment = assignment or ref_assignment
    else:
        if not assignment:
            raise GradeRefused(
                f"cannot tell which assignment {path.name} is: it has no minimanc assignment "
                "metadata (notebooks from `minimanc exercises build` do); pass "
                "--source solutions/NN_name.ipynb"
            )
        source = find_source(path, assignment, roots)
        if source is None:
            looked = ", ".join(str(Path(r) / "solutions") for r in roots) or "-"
            raise GradeRefused(
                f"no solutions notebook for assignment {assignment!r} (looked in {looked} "
                f"and {path.resolve().parent.parent / 'solutions'}); pass --source"
            )
        reference_nb = read_notebook(source, "source")
    try:
        validate(reference_nb, source.name)
    except NotebookFormatError as exc:
        raise GradeRefused(f"source {source}: {_one_line(exc)}") from None
    reference = {grade_id(c): c for c in reference_nb.cells if is_grade_cell(c)}
    if not reference:
        raise GradeRefused(f"source {source} has no grade cells")
    report = GradeReport(notebook=path.name, assignment=assignment, source=str(source))
    built_from = student.metadata.get(META_KEY, {}).get("source_sha256")
    if built_from and built_from != source_fingerprint(reference_nb):
        report.notes.append("the tests changed since this notebook was built; graded with "
                            "the current ones")
    exercise_of = exercise_of_grade_cells(reference_nb)
    forbids = forbidden_functions(reference_nb)

    answers = {grade_id(c): defined_names(cell_source(c))[0]
               for c in reference_nb.cells if is_solution_cell(c)}
    cells, slots = _grading_cells(student, reference, exercise_of, forbids, answers, report)
    # importing the package (nbformat, ...) and capturing are two cells, each well
    # inside the cell timeout
    cells[:0] = [nbformat.v4.new_code_cell(_INTEGRITY + "del _minimanc_integrity"),
                 nbformat.v4.new_code_cell(_capture_source(reference_nb))]
    for slot in slots.values():
        slot.check, slot.grade, slot.probe = slot.check + 2, slot.grade + 2, slot.probe + 2
    run_nb = nbformat.v4.new_notebook(metadata=copy.deepcopy(student.metadata))
    run_nb.cells = cells
    crashed, timed_out = _execute_for_grading(run_nb, path, timeout, report)
    grade_indices = {s.grade for s in slots.values()}
    stopped = len([i for i in timed_out if i not in grade_indices])
    if stopped:
        report.notes.append(f"{stopped} cell(s) of yours stopped: timeout after {timeout} s")
    for gid, ref in reference.items():
        max_points = float(nbgrader_metadata(ref).get("points", 0))
        slot = slots.get(gid)
        if slot is None:
            report.rows.append(GradeRow(
                gid, 0.0, max_points, "missing: grade cell deleted or its metadata removed"
            ))
            continue
        cell = run_nb.cells[slot.grade]
        probe = _stdout(run_nb.cells[slot.probe])
        nonce = slot.nonce
        part = probe.rsplit(":", 1)[-1].strip() if nonce in probe else "?"
        error = _first_error(cell)
        before = _found(run_nb.cells[slot.check], slot.before)
        after = _found(run_nb.cells[slot.probe], slot.after)
        if slot.grade in timed_out:
            row = GradeRow(gid, 0.0, max_points, f"timeout after {timeout} s")
        elif error:
            hidden = slot.labelled and part == "hidden"
            message = f"hidden test failed: {error}" if hidden else error
            row = GradeRow(gid, 0.0, max_points, message, hidden)
        elif cell.execution_count is None:
            row = GradeRow(gid, 0.0, max_points, crashed or "not executed")
        elif f"{nonce}\n" not in _stdout(cell):
            row = GradeRow(gid, 0.0, max_points, "the tests did not run to the end")
        elif before is None or after is None:
            row = GradeRow(gid, 0.0, max_points, "the grader's integrity checks did not run")
        else:
            row = GradeRow(gid, max_points, max_points)
        if after:
            row.points, row.tampered = 0.0, list(after)
            row.message = (f"tampered: your code replaced {_listing(after)} while the tests "
                           "ran; the tests do not count") + (f" ({row.message})" if row.message
                                                             else "")
        elif before:
            row.tampered = list(before)
            row.message = (f"tampered: your code replaced {_listing(before)}; the tests used "
                           "the originals") + (f"; {row.message}" if row.message else "")
        report.rows.append(row)
    return report


def _grading_cells(student, reference, exercise_of, forbids, answers, report):
    """The cells to execute: the student's cells, with each expected grade cell
    replaced by the authoritative one, wrapped in the integrity check, its
    shadowing set-up and its probe (see :func:`grade`)."""
    cells, slots = [], {}
    for cell in student.cells:
        gid = grade_id(cell) if is_grade_cell(cell) else None
        if cell.cell_type != "code":
            continue
        if gid is None or gid not in reference:
            if gid is not None:
                report.notes.append(f"grade cell {gid} is not in the source: not scored")
            cells.append(nbformat.v4.new_code_cell(cell_source(cell)))
            continue
        if gid in slots:
            report.notes.append(f"grade cell {gid} is duplicated; the first copy is scored")
            continue
        exercise = exercise_of.get(gid, gid)
        targets = forbids.get(exercise, [])
        nonce, before, after = (f"minimanc-grade-{secrets.token_hex(8)}" for _ in range(3))
        source = cell_source(reference[gid])
        names = answers.get(exercise, [])
        cells.append(nbformat.v4.new_code_cell(
            _restore_source(before, sorted(read_names(source)), names)))
        check = len(cells) - 1
        if targets:
            cells.append(nbformat.v4.new_code_cell(_setup_source(targets, exercise)))
        src, labelled = instrument_grade_source(source, nonce)
        cells.append(nbformat.v4.new_code_cell(_run_source(src, names, gid)))
        cells.append(nbformat.v4.new_code_cell(_probe_source(nonce, after, bool(targets))))
        slots[gid] = _Slot(check, len(cells) - 2, len(cells) - 1, labelled, nonce, before, after)
    return cells, slots


def _execute_for_grading(nb, path: Path, timeout: int, report: GradeReport):
    """Run every cell, errors allowed.

    Returns (reason execution stopped early or None, indices of timed-out cells).
    """
    from jupyter_client.kernelspec import NoSuchKernel  # Jupyter only when a notebook is executed
    from nbclient.exceptions import DeadKernelError  # Jupyter only when a notebook is executed

    timed_out: set[int] = set()

    def on_executed(cell, cell_index, execute_reply, **_):
        content = (execute_reply or {}).get("content", {})
        if content.get("ename") == TIMEOUT_ENAME:
            timed_out.add(cell_index)

    client = notebook_client(nb, path.resolve().parent, timeout, allow_errors=True)
    client.on_cell_executed = on_executed
    try:
        client.execute()
    except NoSuchKernel as exc:
        raise GradeRefused(f"cannot start a Python kernel: {_one_line(exc)}") from None
    except DeadKernelError:
        report.notes.append("the kernel died; later cells were not run")
        return "not run: the kernel died", timed_out
    except Exception as exc:  # noqa: BLE001 - the grader reports, never crashes
        report.notes.append(f"execution stopped: {type(exc).__name__}: {_one_line(exc)}")
        return f"not run: {type(exc).__name__}", timed_out
    return None, timed_out
