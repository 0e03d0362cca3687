"""Chapter 0 — the notebook machinery: solutions → exercises, execution and grading.

The graded notebooks follow nbgrader's conventions without its database:

* ``solutions/`` is the only hand-edited source of graded sets. The code a student
  must write sits between ``### BEGIN SOLUTION`` and ``### END SOLUTION`` in a
  *solution cell* (metadata ``nbgrader.solution = true``, ``grade_id`` = the
  exercise id, ``minimanc.title`` = its title).
* *Grade cells* (``nbgrader.grade = true``, ``grade_id``, ``points``) hold asserts;
  tests a student should not see sit between ``### BEGIN HIDDEN TESTS`` and
  ``### END HIDDEN TESTS``.
* :func:`build` turns every solution region into
  ``raise NotImplementedError("Exercise <id>: <title>")`` at the marker's
  indentation, removes hidden tests, clears outputs and tags the cells that will
  raise ``raises-exception`` (honoured by nbval), writing ``exercises/``.
* Every graded notebook carries notebook metadata ``minimanc.assignment`` (its
  solutions file's stem); exercise notebooks also carry ``source_sha256``, the
  fingerprint of the tests they were built from.
* :func:`grade` executes a notebook and scores each grade cell against the
  authoritative grade cells (hidden tests included) of
  ``solutions/<assignment>.ipynb``, never against the notebook's own. A
  solution cell may list library functions it asks the student to write
  (``minimanc.forbids``); they raise while that exercise's grade cells run
  (:func:`shadow`).

Notebooks are authored in the "percent" format (:func:`convert`), see
CONTRIBUTING.md.
"""

from __future__ import annotations

import ast
import builtins
import copy
import hashlib
import importlib
import json
import re
import secrets
import types
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import nbformat

from minimanc.errors import UsageError

BEGIN_SOLUTION = "### BEGIN SOLUTION"
END_SOLUTION = "### END SOLUTION"
BEGIN_HIDDEN = "### BEGIN HIDDEN TESTS"
END_HIDDEN = "### END HIDDEN TESTS"
RAISES_TAG = "raises-exception"
DEFAULT_TIMEOUT = 120
TIMEOUT_ENAME = "GradingTimeout"
META_KEY = "minimanc"
"""Key of the notebook- and cell-level metadata this module writes."""
KERNEL_ARGS = ["--IPKernelApp.log_level=ERROR"]
"""Kernel flags: keep the kernel's own start-up warnings (e.g. about its TCP
transport) out of what the student sees."""
_DOTTED = re.compile(r"^[A-Za-z_]\w*(\.[A-Za-z_]\w*)+$")


class NotebookFormatError(ValueError):
    """A graded notebook breaks the marker or metadata rules."""


# --------------------------------------------------------------------------- cells
def _nbgrader(cell) -> dict:
    return cell.get("metadata", {}).get("nbgrader", {}) or {}


def is_grade_cell(cell) -> bool:
    """True for a cell whose tests earn points."""
    return bool(_nbgrader(cell).get("grade"))


def is_solution_cell(cell) -> bool:
    """True for a cell with a solution region to hide."""
    return bool(_nbgrader(cell).get("solution"))


def grade_id(cell) -> str | None:
    """The cell's ``grade_id`` or None."""
    return _nbgrader(cell).get("grade_id")


def _source(cell) -> str:
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
        src = _source(cell)
        lines = src.split("\n")
        _check_markers(lines, where)
        has_solution = bool(_regions(lines, BEGIN_SOLUTION, END_SOLUTION, where))
        has_hidden = bool(_regions(lines, BEGIN_HIDDEN, END_HIDDEN, where))
        gid = grade_id(cell)
        if (has_solution or has_hidden) and cell.cell_type != "code":
            raise NotebookFormatError(f"{where}: markers are only allowed in code cells")
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
            points = _nbgrader(cell).get("points")
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


def source_fingerprint(nb) -> str:
    """sha256 of what grading takes from a solutions notebook: the grade cells
    (id, points, source) and each exercise's forbidden functions."""
    items = []
    for cell in nb.cells:
        if is_grade_cell(cell):
            items.append(["grade", grade_id(cell), _nbgrader(cell).get("points"), _source(cell)])
        elif is_solution_cell(cell):
            items.append(["forbids", grade_id(cell),
                          cell.metadata.get(META_KEY, {}).get("forbids", [])])
    return hashlib.sha256(json.dumps(items, sort_keys=True).encode()).hexdigest()


def assignment_name(nb, name: str) -> str:
    """The assignment id of a solutions notebook: its metadata, else its file stem."""
    meta = nb.get("metadata", {}).get(META_KEY, {})
    value = meta.get("assignment") if isinstance(meta, dict) else None
    return value if isinstance(value, str) and value else Path(name).stem


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
        if cell.cell_type != "code":
            continue
        cell.outputs = []
        cell.execution_count = None
        tags = [t for t in cell.metadata.get("tags", []) if t != RAISES_TAG]
        raises = False
        if is_solution_cell(cell):
            title = cell.metadata.get("minimanc", {}).get("title", "")
            cell.source, raises = stub_solution(_source(cell), grade_id(cell), title, where)
        if is_grade_cell(cell):
            cell.source = strip_hidden(_source(cell), where)
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


# ---------------------------------------------------------------------------- convert
_HEADER = re.compile(r"^# %%(.*)$")
_ATTR = re.compile(r"""(\w+)=("[^"]*"|'[^']*'|\[[^\]]*\]|\S+)""")


_NOQA = re.compile(r"\s+#\s*noqa\b.*$")


def _parse_header(text: str, where: str) -> tuple[str, dict]:
    text = _NOQA.sub("", text.strip())  # a long header may end in a ruff noqa comment
    kind = "code"
    if text.startswith("[markdown]"):
        kind, text = "markdown", text[len("[markdown]"):].strip()
    attrs: dict = {}
    if text.split(" ")[0] in ("solution", "grade"):
        attrs["role"], _, text = text.partition(" ")
    rest = _ATTR.sub("", text).strip()
    if rest:
        raise NotebookFormatError(f"{where}: cannot read cell header attribute {rest!r}")
    for key, value in _ATTR.findall(text):
        try:
            as_json = key in ("tags", "points") or (key == "forbids" and value.startswith("["))
            attrs[key] = json.loads(value) if as_json else value.strip("\"'")
        except json.JSONDecodeError as exc:
            raise NotebookFormatError(f"{where}: {key}={value} is not valid JSON") from exc
    return kind, attrs


def _markdown(lines: list[str]) -> str:
    out = []
    for line in lines:
        if line.startswith("# "):
            out.append(line[2:])
        elif line.strip() == "#":
            out.append("")
        else:
            out.append(line)
    return "\n".join(out).strip("\n")


def cells_from_percent(text: str, name: str = "<source>") -> list:
    """Parse a percent-format script into notebook cells (see CONTRIBUTING.md)."""
    chunks: list[tuple[str, dict, list[str]]] = []
    for number, line in enumerate(text.split("\n"), start=1):
        match = _HEADER.match(line)
        if match:
            kind, attrs = _parse_header(match.group(1), f"{name}: line {number}")
            chunks.append((kind, attrs, []))
        elif chunks:
            chunks[-1][2].append(line)
        elif line.strip():
            raise NotebookFormatError(f"{name}: line {number}: text before the first '# %%'")
    cells = []
    for number, (kind, attrs, lines) in enumerate(chunks):
        if kind == "markdown":
            cells.append(nbformat.v4.new_markdown_cell(_markdown(lines), id=f"c{number:03d}"))
            continue
        cell = nbformat.v4.new_code_cell("\n".join(lines).strip("\n"), id=f"c{number:03d}")
        if attrs.get("tags"):
            cell.metadata["tags"] = list(attrs["tags"])
        role = attrs.get("role")
        if role == "solution":
            cell.metadata["nbgrader"] = {
                "solution": True, "grade": False, "locked": False,
                "grade_id": attrs.get("id", ""), "schema_version": 3,
            }
            cell.metadata[META_KEY] = {"title": attrs.get("title", "")}
            forbids = attrs.get("forbids")
            if forbids:
                if isinstance(forbids, str):
                    forbids = [f for f in re.split(r"[,\s]+", forbids) if f]
                cell.metadata[META_KEY]["forbids"] = list(forbids)
        elif role == "grade":
            cell.metadata["nbgrader"] = {
                "solution": False, "grade": True, "locked": True,
                "grade_id": attrs.get("id", ""), "points": attrs.get("points", 1),
                "schema_version": 3,
            }
        cells.append(cell)
    return cells


def convert(source: Path, target: Path, execute: bool = True, timeout: int = 600):
    """Write the notebook for a percent-format script (and execute it in place)."""
    source, target = Path(source), Path(target)
    nb = nbformat.v4.new_notebook()
    nb.metadata["kernelspec"] = {
        "name": "python3", "display_name": "Python 3", "language": "python"
    }
    nb.metadata["language_info"] = {"name": "python"}
    nb.cells = cells_from_percent(source.read_text(), source.name)
    if any(is_grade_cell(c) or is_solution_cell(c) for c in nb.cells):
        nb.metadata[META_KEY] = {"assignment": target.stem}
        validate(nb, target.name)
    target.parent.mkdir(parents=True, exist_ok=True)
    nbformat.write(nb, target)
    if execute:
        run(target, timeout=timeout)
    return nb


# ------------------------------------------------------------------------ execution
def _client(nb, folder: Path, timeout: int, allow_errors: bool):
    from nbclient import NotebookClient

    return NotebookClient(
        nb,
        timeout=timeout,
        kernel_name="python3",
        allow_errors=allow_errors,
        interrupt_on_timeout=True,
        error_on_timeout={"ename": TIMEOUT_ENAME, "evalue": f"timeout after {timeout} s"},
        extra_arguments=list(KERNEL_ARGS),
        resources={"metadata": {"path": str(folder)}},
    )


def _normalise(nb) -> None:
    """Drop volatile metadata so that committed notebooks diff cleanly."""
    for cell in nb.cells:
        cell.metadata.pop("execution", None)
    nb.metadata.pop("widgets", None)


def run(path: Path, timeout: int = 600) -> None:
    """Execute a notebook in place, stopping at an unexpected error.

    Cells tagged ``raises-exception`` may raise; any other error is re-raised
    with the notebook name and cell index.
    """
    path = Path(path)
    nb = nbformat.read(path, as_version=4)
    client = _client(nb, path.resolve().parent, timeout, allow_errors=True)
    client.execute()
    for index, cell in enumerate(nb.cells):
        if cell.cell_type != "code" or RAISES_TAG in cell.metadata.get("tags", []):
            continue
        for output in cell.get("outputs", []):
            if output.get("output_type") == "error":
                raise RuntimeError(
                    f"{path.name}: cell {index} raised {output.get('ename')}: "
                    f"{output.get('evalue')}"
                )
    _normalise(nb)
    nbformat.write(nb, path)


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
            "rows": [dict(r.__dict__) for r in self.rows],
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


def _probe_source(nonce: str, guarded: bool) -> str:
    restore = f"    {_GUARD}.restore()\n" if guarded else "    pass\n"
    return (
        f"try:\n{restore}finally:\n"
        f"    print({nonce!r} + ':' + str(globals().get({_PART!r}, '?')))"
    )


@dataclass
class _Slot:
    """Where one expected grade cell sits in the notebook being executed."""

    grade: int
    probe: int
    labelled: bool


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

    cells, slots, nonce = _grading_cells(student, reference, exercise_of, forbids, report)
    run_nb = nbformat.v4.new_notebook(metadata=copy.deepcopy(student.metadata))
    run_nb.cells = cells
    crashed, timed_out = _execute_for_grading(run_nb, path, timeout, report)
    grade_indices = {s.grade for s in slots.values()}
    stopped = len([i for i in timed_out if i not in grade_indices])
    if stopped:
        report.notes.append(f"{stopped} cell(s) of yours stopped: timeout after {timeout} s")
    for gid, ref in reference.items():
        max_points = float(_nbgrader(ref).get("points", 0))
        slot = slots.get(gid)
        if slot is None:
            report.rows.append(GradeRow(
                gid, 0.0, max_points, "missing: grade cell deleted or its metadata removed"
            ))
            continue
        cell = run_nb.cells[slot.grade]
        probe = _stdout(run_nb.cells[slot.probe])
        part = probe.rsplit(":", 1)[-1].strip() if nonce in probe else "?"
        error = _first_error(cell)
        if slot.grade in timed_out:
            report.rows.append(GradeRow(gid, 0.0, max_points, f"timeout after {timeout} s"))
        elif error:
            hidden = slot.labelled and part == "hidden"
            message = f"hidden test failed: {error}" if hidden else error
            report.rows.append(GradeRow(gid, 0.0, max_points, message, hidden))
        elif cell.execution_count is None:
            report.rows.append(GradeRow(gid, 0.0, max_points, crashed or "not executed"))
        elif f"{nonce}\n" not in _stdout(cell):
            report.rows.append(GradeRow(gid, 0.0, max_points, "the tests did not run to the end"))
        else:
            report.rows.append(GradeRow(gid, max_points, max_points))
    return report


def _grading_cells(student, reference, exercise_of, forbids, report):
    """The cells to execute: the student's cells, with each expected grade cell
    replaced by the authoritative one, wrapped in its shadowing set-up and probe."""
    nonce = f"minimanc-grade-{secrets.token_hex(8)}"
    cells, slots = [], {}
    for cell in student.cells:
        gid = grade_id(cell) if is_grade_cell(cell) else None
        if cell.cell_type != "code":
            continue
        if gid is None or gid not in reference:
            if gid is not None:
                report.notes.append(f"grade cell {gid} is not in the source: not scored")
            cells.append(nbformat.v4.new_code_cell(_source(cell)))
            continue
        if gid in slots:
            report.notes.append(f"grade cell {gid} is duplicated; the first copy is scored")
            continue
        exercise = exercise_of.get(gid, gid)
        targets = forbids.get(exercise, [])
        if targets:
            cells.append(nbformat.v4.new_code_cell(_setup_source(targets, exercise)))
        src, labelled = instrument_grade_source(_source(reference[gid]), nonce)
        cells.append(nbformat.v4.new_code_cell(src))
        cells.append(nbformat.v4.new_code_cell(_probe_source(nonce, bool(targets))))
        slots[gid] = _Slot(len(cells) - 2, len(cells) - 1, labelled)
    return cells, slots, nonce


def _execute_for_grading(nb, path: Path, timeout: int, report: GradeReport):
    """Run every cell, errors allowed.

    Returns (reason execution stopped early or None, indices of timed-out cells).
    """
    from jupyter_client.kernelspec import NoSuchKernel
    from nbclient.exceptions import DeadKernelError

    timed_out: set[int] = set()

    def on_executed(cell, cell_index, execute_reply, **_):
        content = (execute_reply or {}).get("content", {})
        if content.get("ename") == TIMEOUT_ENAME:
            timed_out.add(cell_index)

    client = _client(nb, path.resolve().parent, timeout, allow_errors=True)
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


# ------------------------------------------------------------------ library shadowing
class ForbiddenFunctionError(RuntimeError):
    """A library function an exercise asks the student to write was called while grading."""


def resolve(dotted: str) -> tuple[Any, str, Any]:
    """(owner module or object, attribute name, value) of ``pkg.module.attr``."""
    parts = dotted.split(".")
    for cut in range(len(parts) - 1, 0, -1):
        try:
            owner = importlib.import_module(".".join(parts[:cut]))
        except ImportError:
            continue
        for name in parts[cut:-1]:
            owner = getattr(owner, name)
        return owner, parts[-1], getattr(owner, parts[-1])
    raise ImportError(f"cannot import {dotted!r}")


def _blocker_code(message: str, n_free: int) -> types.CodeType:
    """Code of ``lambda *a, **k: raise ForbiddenFunctionError(message)`` with
    ``n_free`` free variables, so it can replace the code of a closure too."""
    names = [f"_free{i}" for i in range(n_free)]
    assign = "".join(f"    {n} = None\n" for n in names)
    touch = "".join(f"        {n}\n" for n in names)
    text = (
        "def _outer():\n" + assign +
        "    def blocked(*args, **kwargs):\n" + touch +
        "        raise __import__('minimanc.exercises', fromlist=['x'])"
        f".ForbiddenFunctionError({message!r})\n"
        "    return blocked\n"
    )
    scope: dict = {}
    exec(compile(text, "<minimanc grading>", "exec"), scope)  # noqa: S102 - fixed template
    return scope["_outer"]().__code__


class Shadow:
    """Library functions disabled while an exercise's grade cells run; see :func:`shadow`."""

    def __init__(self) -> None:
        self._codes: list[tuple[types.FunctionType, types.CodeType]] = []
        self._attrs: list[tuple[Any, str, Any]] = []

    def restore(self) -> None:
        """Put every disabled function back (idempotent)."""
        for fn, code in reversed(self._codes):
            fn.__code__ = code
        for owner, name, value in reversed(self._attrs):
            if isinstance(owner, dict):
                owner[name] = value
            else:
                setattr(owner, name, value)
        self._codes, self._attrs = [], []


def shadow(targets: Sequence[str], exercise: str, namespace: dict | None = None) -> Shadow:
    """Make each library function in ``targets`` raise :class:`ForbiddenFunctionError`.

    A Python function has its code replaced, so every reference to it fails: the
    module attribute, a name bound earlier (``from minimanc.dmp import classify``,
    ``classify = dmp.classify``), a wrapper calling it, and copies of it found in
    ``namespace`` (the student's globals). Other callables are replaced in their
    module and wherever ``namespace`` binds them. Call ``restore()`` afterwards.
    Targets that cannot be imported are skipped.
    """
    guard = Shadow()
    namespace = namespace if namespace is not None else {}
    for dotted in targets:
        try:
            owner, attr, value = resolve(dotted)
        except (ImportError, AttributeError):
            continue
        message = (f"Exercise {exercise}: write {attr} yourself; {dotted} is disabled "
                   "while grading")
        if isinstance(value, types.FunctionType):
            original = value.__code__
            same = [value] + [
                v for v in namespace.values()
                if isinstance(v, types.FunctionType) and v is not value and v.__code__ is original
            ]
            for fn in same:
                guard._codes.append((fn, fn.__code__))
                fn.__code__ = _blocker_code(message, len(fn.__code__.co_freevars))
            continue
        blocker = types.FunctionType(_blocker_code(message, 0), {"__builtins__": builtins})
        guard._attrs.append((owner, attr, value))
        setattr(owner, attr, blocker)
        for name, bound in list(namespace.items()):
            if bound is value:
                guard._attrs.append((namespace, name, bound))
                namespace[name] = blocker
    return guard
