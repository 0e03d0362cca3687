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
* :func:`grade` executes a notebook and scores each grade cell, taking the
  authoritative grade cells (hidden tests included) from ``solutions/``.

Notebooks are authored in the "percent" format (:func:`convert`), see
CONTRIBUTING.md.
"""

from __future__ import annotations

import copy
import json
import re
from dataclasses import dataclass, field
from pathlib import Path

import nbformat

BEGIN_SOLUTION = "### BEGIN SOLUTION"
END_SOLUTION = "### END SOLUTION"
BEGIN_HIDDEN = "### BEGIN HIDDEN TESTS"
END_HIDDEN = "### END HIDDEN TESTS"
RAISES_TAG = "raises-exception"
DEFAULT_TIMEOUT = 120


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
            if not isinstance(points, (int, float)) or points <= 0:
                raise NotebookFormatError(f"{where}: grade cell {gid!r} needs positive points")
        if is_solution_cell(cell):
            exercises.append(gid)
    return exercises


# ----------------------------------------------------------------------------- build
def make_exercise(nb, name: str):
    """The student version of a solutions notebook (a new notebook object)."""
    validate(nb, name)
    out = copy.deepcopy(nb)
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


def _parse_header(text: str, where: str) -> tuple[str, dict]:
    text = text.strip()
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
            attrs[key] = json.loads(value) if key in ("tags", "points") else value.strip("\"'")
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
            cell.metadata["minimanc"] = {"title": attrs.get("title", "")}
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
        error_on_timeout={"ename": "Timeout", "evalue": f"cell ran longer than {timeout} s"},
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
@dataclass
class GradeRow:
    """One grade cell's result."""

    grade_id: str
    points: float
    max_points: float
    message: str = ""


@dataclass
class GradeReport:
    """Points per grade cell, plus notes on what went wrong with the notebook."""

    notebook: str
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
            "total": self.total,
            "max_total": self.max_total,
            "rows": [r.__dict__ for r in self.rows],
            "notes": self.notes,
        }

    def format(self) -> str:
        width = max([len(r.grade_id) for r in self.rows] + [8])
        lines = [f"{self.notebook}"]
        for r in self.rows:
            mark = "ok  " if r.points == r.max_points else "FAIL"
            tail = f"  {r.message}" if r.message else ""
            lines.append(f"  {mark} {r.grade_id:<{width}} {r.points:g}/{r.max_points:g}{tail}")
        lines.extend(f"  note: {n}" for n in self.notes)
        lines.append(f"  total {self.total:g}/{self.max_total:g}")
        return "\n".join(lines)


def find_source(path: Path) -> Path | None:
    """The solutions notebook whose grade cells are authoritative for ``path``."""
    path = Path(path).resolve()
    candidate = path.parent.parent / "solutions" / path.name
    if candidate.exists() and candidate != path:
        return candidate
    return None


def _first_error(cell) -> str | None:
    for output in cell.get("outputs", []):
        if output.get("output_type") == "error":
            value = str(output.get("evalue", "")).strip().split("\n")[0]
            return f"{output.get('ename', 'Error')}: {value}" if value else output.get("ename")
    return None


def _prepare(student, reference, report: GradeReport) -> dict[str, int]:
    """Put the authoritative grade cells into the student's notebook.

    Returns grade_id → index of the cell to score in ``student``.
    """
    positions: dict[str, int] = {}
    for index, cell in enumerate(student.cells):
        gid = grade_id(cell)
        if not is_grade_cell(cell) or not gid:
            continue
        if gid in positions:
            report.notes.append(f"grade cell {gid} is duplicated; the first copy is scored")
            cell.source = "# duplicate of a grade cell: not scored"
            cell.metadata["nbgrader"] = {}
            continue
        positions[gid] = index
        if gid in reference:
            cell.source = _source(reference[gid])
    return positions


def grade(path: Path, source: Path | None = None, timeout: int = DEFAULT_TIMEOUT) -> GradeReport:
    """Execute the notebook at ``path`` and score each grade cell.

    Grade cells are matched by ``grade_id``: moved cells are fine, a deleted grade
    cell scores 0, a duplicated one is scored once. A cell that runs longer than
    ``timeout`` seconds is interrupted; a crashed kernel leaves the remaining
    cells unscored. The grader reports these and never raises for them.
    """
    path = Path(path)
    report = GradeReport(notebook=path.name)
    try:
        student = nbformat.read(path, as_version=4)
    except FileNotFoundError:
        report.notes.append(f"no notebook at {path.name}")
        return report
    except Exception as exc:  # noqa: BLE001 - any unreadable file is reported
        report.notes.append(f"cannot read notebook: {type(exc).__name__}: {exc}")
        return report
    source = Path(source) if source else find_source(path)
    reference_nb = nbformat.read(source, as_version=4) if source else student
    reference = {grade_id(c): c for c in reference_nb.cells if is_grade_cell(c) and grade_id(c)}
    if not reference:
        report.notes.append("no grade cells found")
        return report
    student = copy.deepcopy(student)
    for cell in student.cells:
        if cell.cell_type == "code":
            cell.outputs, cell.execution_count = [], None
    positions = _prepare(student, reference, report)
    crashed = _execute_for_grading(student, path, timeout, report)
    for gid, ref in reference.items():
        max_points = float(_nbgrader(ref).get("points", 0))
        if gid not in positions:
            report.rows.append(GradeRow(gid, 0.0, max_points, "grade cell deleted"))
            continue
        cell = student.cells[positions[gid]]
        error = _first_error(cell)
        if error:
            report.rows.append(GradeRow(gid, 0.0, max_points, error))
        elif cell.execution_count is None:
            why = crashed or "not executed"
            report.rows.append(GradeRow(gid, 0.0, max_points, why))
        else:
            report.rows.append(GradeRow(gid, max_points, max_points))
    return report


def _execute_for_grading(nb, path: Path, timeout: int, report: GradeReport) -> str | None:
    """Run every cell, errors allowed; returns a reason if execution stopped early."""
    from nbclient.exceptions import DeadKernelError

    client = _client(nb, path.resolve().parent, timeout, allow_errors=True)
    try:
        client.execute()
    except DeadKernelError:
        report.notes.append("the kernel died; later cells were not run")
        return "not run: the kernel died"
    except Exception as exc:  # noqa: BLE001 - the grader reports, never crashes
        report.notes.append(f"execution stopped: {type(exc).__name__}: {exc}")
        return f"not run: {type(exc).__name__}"
    return None
