"""Chapter 0 — grading a notebook against the authoritative tests of its solutions notebook.

:func:`grade` executes a notebook and scores each grade cell against the grade cells
(hidden tests included) of ``solutions/<assignment>.ipynb``, never against the
notebook's own. The grade cells run in a separate process that no student cell can
reach (:mod:`minimanc.exercises.checker`): it runs the solutions notebook's own plain
cells, and when the notebook reaches a grade cell the notebook answers the tests' calls
of its functions with plain data (:mod:`minimanc.exercises.serving`,
:mod:`minimanc.exercises.values`); while an exercise is graded, the library functions it
``forbids`` raise in the notebook (:func:`minimanc.exercises.shadow`). Written answers
(markdown answer cells) are graded by hand: the report lists them apart, with their
points and whether the student wrote anything, and never adds them to the automatic
total.
"""

from __future__ import annotations

import ast
import copy
import json
import re
import sys
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import nbformat

from minimanc.errors import UsageError
from minimanc.exercises.checker import TestsProcess, TestsStopped
from minimanc.exercises.conversion import TIMEOUT_ENAME, notebook_client
from minimanc.exercises.markers import (
    META_KEY,
    RAISES_TAG,
    NotebookFormatError,
    answer_written,
    cell_source,
    grade_id,
    is_answer_cell,
    is_grade_cell,
    is_solution_cell,
    nbgrader_metadata,
    source_fingerprint,
    stub_answer,
    validate,
)

__all__ = [
    "AnswerRow",
    "DEFAULT_TIMEOUT",
    "GradeRefused",
    "GradeReport",
    "GradeRow",
    "answer_names",
    "assignment_of",
    "exercise_of_grade_cells",
    "find_source",
    "forbidden_functions",
    "grade",
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
    title: str = ""


@dataclass
class AnswerRow:
    """One written answer to grade by hand: its points (never in the automatic
    total) and whether the student's cell differs from ``YOUR ANSWER HERE``;
    ``found`` is False when the cell was deleted or lost its metadata."""

    grade_id: str
    max_points: float
    title: str = ""
    written: bool = False
    found: bool = True


@dataclass
class GradeReport:
    """Points per grade cell, the written answers to grade by hand, and notes on
    what went wrong with the notebook."""

    notebook: str
    assignment: str = ""
    source: str = ""
    rows: list[GradeRow] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    answers: list[AnswerRow] = field(default_factory=list)

    @property
    def total(self) -> float:
        return sum(r.points for r in self.rows)

    @property
    def max_total(self) -> float:
        """The automatic maximum (written answers are not in it)."""
        return sum(r.max_points for r in self.rows)

    @property
    def percent(self) -> float:
        """The automatic total as a percentage of its maximum (0 when there is none)."""
        return 100.0 * self.total / self.max_total if self.max_total else 0.0

    @property
    def hand_max_total(self) -> float:
        """The points of the written answers, graded by hand."""
        return sum(a.max_points for a in self.answers)

    def to_dict(self) -> dict:
        return {
            "notebook": self.notebook,
            "assignment": self.assignment,
            "source": self.source,
            "total": self.total,
            "max_total": self.max_total,
            "percent": self.percent,
            "rows": [copy.deepcopy(r.__dict__) for r in self.rows],
            "to_grade_by_hand": [copy.deepcopy(a.__dict__) for a in self.answers],
            "hand_max_total": self.hand_max_total,
            "notes": self.notes,
        }

    def format(self) -> str:
        width = max([len(r.grade_id) for r in self.rows + self.answers] + [8])
        titles = max([len(r.title) for r in self.rows + self.answers] + [0])
        head = f"{self.notebook} (assignment {self.assignment})" if self.assignment else ""
        lines = [head or self.notebook]
        for r in self.rows:
            mark = "ok  " if r.points == r.max_points else "FAIL"
            tail = f"  {r.message}" if r.message else ""
            title = f" {r.title:<{titles}}" if titles else ""
            lines.append(f"  {mark} {r.grade_id:<{width}}{title} "
                         f"{r.points:g}/{r.max_points:g}{tail}")
        lines.extend(f"  note: {n}" for n in self.notes)
        lines.append(f"  total {self.total:g}/{self.max_total:g} ({self.percent:.0f}%) automatic")
        if self.answers:
            lines.append(f"  to grade by hand (not in the total): {self.hand_max_total:g} "
                         "point(s)")
            for a in self.answers:
                state = ("written" if a.written else "empty: YOUR ANSWER HERE") if a.found \
                    else "missing: answer cell deleted or its metadata removed"
                title = f" {a.title:<{titles}}" if titles else ""
                lines.append(f"       {a.grade_id:<{width}}{title} {a.max_points:g} point(s)  "
                             f"{state}")
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


def answer_names(nb) -> list[str]:
    """The names the solution cells bind at top level (functions, classes, values): the
    names whose values the tests take from the student's notebook."""
    names: list[str] = []
    for cell in nb.cells:
        if not is_solution_cell(cell):
            continue
        try:
            tree = ast.parse(cell_source(cell))
        except SyntaxError:
            continue
        for node in tree.body:
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                names.append(node.name)
            elif isinstance(node, (ast.Assign, ast.AnnAssign, ast.AugAssign)):
                targets = node.targets if isinstance(node, ast.Assign) else [node.target]
                names += [n.id for t in targets for n in ast.walk(t) if isinstance(n, ast.Name)]
    return sorted(set(names))


def _tests_cells(reference_nb) -> list[dict]:
    """The solutions notebook's code cells as the tests' process runs them: its plain
    cells and its grade cells (never its solution cells)."""
    out = []
    for index, cell in enumerate(reference_nb.cells):
        if cell.cell_type != "code" or is_solution_cell(cell):
            continue
        grade_cell = is_grade_cell(cell)
        out.append({"kind": "grade" if grade_cell else "plain", "source": cell_source(cell),
                    "index": index, "gid": grade_id(cell) if grade_cell else None,
                    "raises": RAISES_TAG in cell.metadata.get("tags", [])})
    return out


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
    never trusted, and they run in a process of their own (see the module docstring).
    Grade cells are matched by ``grade_id``: moved cells are fine; a deleted one (or
    one whose metadata was removed) scores 0 and is listed; a duplicated one is scored
    once. While an exercise's grade cells run, the library functions it ``forbids``
    raise (see :func:`shadow`). A cell that runs longer than ``timeout`` seconds is
    interrupted; a crashed kernel leaves the remaining cells unscored.

    Raises :class:`GradeRefused` when the notebook cannot be read, its source cannot
    be identified or the tests' process cannot start; otherwise never raises for what
    the notebook does.
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
    titles = {grade_id(c): str(c.metadata.get(META_KEY, {}).get("title", ""))
              for c in reference_nb.cells if is_solution_cell(c)}
    report.answers = _answer_rows(student, reference_nb, source.name)

    cells, slots = _grading_cells(student, reference, report)
    names = answer_names(reference_nb)
    try:
        tests = TestsProcess(_tests_cells(reference_nb), list(slots), names,
                             source.resolve().parent, timeout, _kernel_python())
    except OSError as exc:
        raise GradeRefused(f"cannot start the tests' process: {_one_line(exc)}") from None
    try:
        forbids = forbidden_functions(reference_nb)
        serving = {}
        for gid, index in slots.items():   # the serving cells are written when reached
            exercise = exercise_of.get(gid, gid)
            cells[index] = nbformat.v4.new_code_cell("pass")
            serving[gid] = (exercise, forbids.get(exercise, []), names)
        # importing the serving side (nbformat, ...) is a cell of its own, well inside the
        # cell timeout
        cells.insert(0, nbformat.v4.new_code_cell(_SERVING))
        slots = {gid: index + 1 for gid, index in slots.items()}
        run_nb = nbformat.v4.new_notebook(metadata=copy.deepcopy(student.metadata))
        run_nb.cells = cells
        run = _Run(tests, slots, serving)
        crashed, timed_out = _execute_for_grading(run_nb, path, timeout, report, run)
    finally:
        tests.stop()
    stopped = len([i for i in timed_out if i not in set(slots.values())])
    if stopped:
        report.notes.append(f"{stopped} cell(s) of yours stopped: timeout after {timeout} s")
    report.notes += [f"the tests' own setup failed ({e}); tell your instructor"
                     for e in tests.setup_errors]
    for gid, ref in reference.items():
        max_points = float(nbgrader_metadata(ref).get("points", 0))
        row = GradeRow(gid, 0.0, max_points, title=titles.get(exercise_of.get(gid, gid), ""))
        index = slots.get(gid)
        verdict = tests.verdicts.get(gid) if index is not None else None
        if index is None:
            row.message = "missing: grade cell deleted or its metadata removed"
        elif index in timed_out:
            row.message = f"timeout after {timeout} s"
        elif gid in run.stalled:
            row.message = f"not run: {run.stalled[gid]}"
        elif run_nb.cells[index].execution_count is None:
            row.message = crashed or "not executed"
        elif verdict is None or "passed" not in verdict:
            error = _first_error(run_nb.cells[index])
            row.message = "the tests did not run" + (f": {error}" if error else "")
        elif verdict["passed"]:
            row.points = max_points
        else:
            row.hidden = bool(verdict.get("hidden"))
            message = str(verdict.get("message", ""))
            row.message = f"hidden test failed: {message}" if row.hidden else message
        report.rows.append(row)
    return report


_SERVING = "import minimanc.exercises.serving\ndel minimanc"


def _kernel_python() -> str | None:
    """The interpreter of the ``python3`` kernel (the tests' process uses the same one, so
    functions sent by their code run there); None for this one."""
    from jupyter_client.kernelspec import KernelSpecManager  # Jupyter only when grading

    try:
        argv = KernelSpecManager().get_kernel_spec("python3").argv
    except Exception:  # noqa: BLE001 - no such kernelspec: the kernel start reports it
        return None
    plain = {"python", f"python{sys.version_info[0]}", "python{}.{}".format(*sys.version_info)}
    return None if not argv or argv[0] in plain else argv[0]


class _Run:
    """What happens around the serving cells while the notebook runs: before one, wait
    until the tests' process is ready for it; after one, make sure it is not waiting
    for a grade cell that will never come."""

    def __init__(self, tests: TestsProcess, slots: dict[str, int],
                 serving: dict[str, tuple]) -> None:
        self.tests, self.serving = tests, serving
        self.at = {index: gid for gid, index in slots.items()}
        self.stalled: dict[str, str] = {}

    def start(self) -> None:
        """Once the kernel is up, before its first cell: the tests' process must be
        listening (it started first; the two start side by side)."""
        try:
            self.tests.started()
        except TestsStopped as exc:
            raise GradeRefused(f"cannot start the tests' process: {_one_line(exc)}") from None

    def before(self, cell, cell_index: int) -> None:
        gid = self.at.get(cell_index)
        if gid is None:
            return
        try:
            self.tests.wait_ready(gid)
        except TestsStopped as exc:
            self.stalled[gid] = str(exc)
            return
        cell.source = self.tests.serve_source(gid, *self.serving[gid])

    def after(self, cell_index: int) -> None:
        gid = self.at.get(cell_index)
        if gid is not None and gid not in self.stalled and self.tests.verdict(gid) is None:
            self.tests.skip(gid)


def _answer_rows(student, reference_nb, name: str) -> list[AnswerRow]:
    """The written answers of the solutions notebook, matched by ``grade_id`` in the
    student's notebook (points and title always from the solutions)."""
    mine: dict[str, str] = {}
    for cell in student.cells:
        gid = grade_id(cell) if is_answer_cell(cell) else None
        if gid and gid not in mine:
            mine[gid] = cell_source(cell)
    rows = []
    for index, cell in enumerate(reference_nb.cells):
        if not is_answer_cell(cell):
            continue
        gid = grade_id(cell)
        stub = stub_answer(cell_source(cell), f"{name}: cell {index}")
        rows.append(AnswerRow(
            gid, float(nbgrader_metadata(cell).get("points", 0)),
            str(cell.metadata.get(META_KEY, {}).get("title", "")),
            written=gid in mine and answer_written(mine[gid], stub), found=gid in mine,
        ))
    return rows


def _grading_cells(student, reference, report):
    """The cells to execute: the student's code cells, each expected grade cell replaced
    by a placeholder for its serving cell (``slots``: grade id -> its index)."""
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
        slots[gid] = len(cells)
        cells.append(None)
    return cells, slots


def _execute_for_grading(nb, path: Path, timeout: int, report: GradeReport, run: _Run):
    """Run every cell, errors allowed.

    Returns (reason execution stopped early or None, indices of timed-out cells).
    """
    from jupyter_client.kernelspec import NoSuchKernel  # Jupyter only when a notebook is executed
    from nbclient.exceptions import DeadKernelError  # Jupyter only when a notebook is executed

    timed_out: set[int] = set()

    def on_execute(cell, cell_index, **_):
        run.before(cell, cell_index)

    def on_executed(cell, cell_index, execute_reply, **_):
        content = (execute_reply or {}).get("content", {})
        if content.get("ename") == TIMEOUT_ENAME:
            timed_out.add(cell_index)
        run.after(cell_index)

    client = notebook_client(nb, path.resolve().parent, timeout, allow_errors=True)
    client.on_notebook_start = lambda **_: run.start()
    client.on_cell_execute = on_execute
    client.on_cell_executed = on_executed
    try:
        client.execute()
    except NoSuchKernel as exc:
        raise GradeRefused(f"cannot start a Python kernel: {_one_line(exc)}") from None
    except GradeRefused:
        raise
    except DeadKernelError:
        report.notes.append("the kernel died; later cells were not run")
        return "not run: the kernel died", timed_out
    except Exception as exc:  # noqa: BLE001 - the grader reports, never crashes
        report.notes.append(f"execution stopped: {type(exc).__name__}: {_one_line(exc)}")
        return f"not run: {type(exc).__name__}", timed_out
    return None, timed_out
