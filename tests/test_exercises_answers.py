"""Written answers graded by hand: the answer cell, its stub, its validation and its
place in the grade report (listed apart, never in the automatic total)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import nbformat
import pytest

from minimanc import exercises
from minimanc.exercises import NotebookFormatError

ROOT = Path(__file__).resolve().parent.parent

HW = '''# %%
import math

# %% solution id=ex_a title="Square root"
def root(x):
    ### BEGIN SOLUTION
    return math.sqrt(x)
    ### END SOLUTION

# %% grade id=ex_a_tests points=2
got = root(9.0)
assert got == 3.0, f"x = 9: expected 3.0, got {got}"

# %% [markdown]
# **Question.** Why does the square root of a negative number fail here?

# %% [markdown] answer id=ex_a_w title="Negative input" points=3
# ### BEGIN SOLUTION
# `math.sqrt` works on real numbers; the root of x < 0 is complex (`cmath.sqrt`).
# ### END SOLUTION
'''

ANSWER_META = {"solution": True, "grade": True, "task": False, "points": 2, "grade_id": "ex_w"}


def answer_nb(source: str, meta: dict | None = None, kind: str = "markdown"):
    nb = nbformat.v4.new_notebook()
    make = nbformat.v4.new_markdown_cell if kind == "markdown" else nbformat.v4.new_code_cell
    cell = make(source)
    cell.metadata["nbgrader"] = dict(ANSWER_META if meta is None else meta)
    nb.cells = [nbformat.v4.new_markdown_cell("intro"), cell]
    return nb


MODEL = "Before.\n### BEGIN SOLUTION\nThe model answer.\n### END SOLUTION\nAfter."


# ------------------------------------------------------------------ source and builder
def test_percent_header_makes_an_nbgrader_manually_graded_answer_cell():
    cells = exercises.cells_from_percent(HW, "hw.py")
    cell = cells[-1]
    assert cell.cell_type == "markdown"
    assert cell.metadata["nbgrader"] == {
        "solution": True, "grade": True, "task": False, "locked": False,
        "grade_id": "ex_a_w", "points": 3, "schema_version": 3,
    }
    assert cell.metadata["minimanc"]["title"] == "Negative input"
    assert cell.source.startswith("### BEGIN SOLUTION\n`math.sqrt`")
    assert exercises.is_answer_cell(cell)
    assert not exercises.is_grade_cell(cell) and not exercises.is_solution_cell(cell)


@pytest.mark.parametrize("header, message", [
    ("# %% answer id=ex_w points=2", "'answer' needs a '# %% [markdown]' header"),
    ("# %% [markdown] solution id=ex_w", "'solution' needs a code cell"),
])
def test_percent_header_refuses_an_answer_in_the_wrong_cell_kind(header, message):
    with pytest.raises(NotebookFormatError, match="src.py: line 1") as info:
        exercises.cells_from_percent(header + "\n# text\n", "src.py")
    assert message in str(info.value)


def test_build_replaces_the_model_answer_with_nbgraders_placeholder():
    nb = answer_nb(MODEL)
    ex = exercises.make_exercise(nb, "w.ipynb")
    assert ex.cells[1].source == "Before.\nYOUR ANSWER HERE\nAfter."
    assert ex.cells[1].metadata["nbgrader"] == ANSWER_META   # kept: the grader finds it
    assert "The model answer." in nb.cells[1].source         # the solutions are untouched
    assert "tags" not in ex.cells[1].metadata                 # a markdown cell never raises


def test_the_fingerprint_changes_with_the_points_of_a_written_answer():
    one, two = answer_nb(MODEL), answer_nb(MODEL, {**ANSWER_META, "points": 3})
    assert exercises.source_fingerprint(one) != exercises.source_fingerprint(two)
    plain = nbformat.v4.new_notebook()
    assert exercises.source_fingerprint(one) != exercises.source_fingerprint(plain)


def test_answer_written_ignores_whitespace_only():
    stub = "Before.\nYOUR ANSWER HERE\nAfter."
    assert not exercises.answer_written("Before.\n  YOUR ANSWER HERE \n\nAfter.", stub)
    assert exercises.answer_written("Before.\nThe step is unstable.\nAfter.", stub)
    assert not exercises.answer_written("", stub)                 # emptied: nothing written
    assert not exercises.answer_written("YOUR ANSWER HERE", stub)  # the prompt lines deleted
    assert exercises.answer_written("YOUR ANSWER HERE. It diverges.", stub)


# ------------------------------------------------------------------ validation
@pytest.mark.parametrize("source, meta, kind, message", [
    (MODEL, {**ANSWER_META, "points": 0}, "markdown", "answer cell 'ex_w' needs positive points"),
    (MODEL, {**ANSWER_META, "points": True}, "markdown", "needs positive points"),
    (MODEL, {**ANSWER_META, "grade_id": ""}, "markdown", "answer cell without a grade_id"),
    (MODEL, {**ANSWER_META, "task": True}, "markdown", "cannot be a task"),
    ("No markers.", ANSWER_META, "markdown", "without a model answer between"),
    ("### BEGIN SOLUTION\nx\n### END SOLUTION\n### BEGIN HIDDEN TESTS\n### END HIDDEN TESTS",
     ANSWER_META, "markdown", "cannot hold hidden tests"),
    ("### BEGIN SOLUTION\nnever closed", ANSWER_META, "markdown",
     "unclosed '### BEGIN SOLUTION' at line 1"),
    (MODEL, {**ANSWER_META, "grade": False}, "markdown",
     "a markdown cell marked solution or grade must be an answer cell"),
    (MODEL, {}, "markdown", "markers are only allowed in code cells and answer cells"),
])
def test_validate_names_what_is_wrong_with_an_answer_cell(source, meta, kind, message):
    nb = answer_nb(source, meta, kind)
    with pytest.raises(NotebookFormatError) as info:
        exercises.validate(nb, "w.ipynb")
    assert "w.ipynb: cell 1" in str(info.value) and message in str(info.value)


def test_validate_refuses_an_answer_id_taken_by_a_grade_cell():
    nb = answer_nb(MODEL)
    grade = nbformat.v4.new_code_cell("assert True")
    grade.metadata["nbgrader"] = {"solution": False, "grade": True, "grade_id": "ex_w",
                                  "points": 1}
    nb.cells.append(grade)
    with pytest.raises(NotebookFormatError, match="cell 2: duplicate grade_id 'ex_w'"):
        exercises.validate(nb, "w.ipynb")


def test_validate_accepts_an_answer_cell_and_returns_only_code_exercises():
    assert exercises.validate(answer_nb(MODEL), "w.ipynb") == []


# ------------------------------------------------------------------ the grade report
@pytest.fixture(scope="module")
def course(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("course")
    (root / "hw_solutions.py").write_text(HW)
    exercises.convert(root / "hw_solutions.py", root / "solutions" / "hw.ipynb")
    exercises.build(root / "solutions", root / "exercises")
    return root


def edited(course: Path, name: str, code: str | None, answer: str | None,
           drop_answer: bool = False) -> Path:
    """A copy of exercises/hw.ipynb with the solution cell and the answer replaced."""
    nb = nbformat.read(course / "exercises" / "hw.ipynb", as_version=4)
    for cell in nb.cells:
        if exercises.is_solution_cell(cell) and code is not None:
            cell.source = code
        if exercises.is_answer_cell(cell) and answer is not None:
            cell.source = answer
            cell.metadata["nbgrader"]["points"] = 100   # the student's metadata never counts
    if drop_answer:
        nb.cells = [c for c in nb.cells if not exercises.is_answer_cell(c)]
    path = course / "exercises" / name
    nbformat.write(nb, path)
    return path


def test_grade_lists_written_answers_apart_from_the_automatic_total(course):
    path = edited(course, "mine.ipynb", "def root(x):\n    return math.sqrt(x)",
                  "sqrt of a negative real has no real value")
    report = exercises.grade(path)
    assert report.total == report.max_total == 2          # the 3 written points are not in it
    assert report.percent == 100.0
    [answer] = report.answers
    assert (answer.grade_id, answer.title, answer.max_points) == ("ex_a_w", "Negative input", 3)
    assert answer.written and answer.found
    assert report.rows[0].title == "Square root"
    text = report.format()
    assert "ex_a_tests Square root    2/2" in text
    assert "total 2/2 (100%) automatic" in text
    assert "to grade by hand (not in the total): 3 point(s)" in text
    assert "ex_a_w     Negative input 3 point(s)  written" in text
    assert text.index("total 2/2") < text.index("to grade by hand")


def test_grade_says_when_the_answer_is_still_the_placeholder_or_missing(course):
    report = exercises.grade(course / "exercises" / "hw.ipynb")
    assert report.total == 0 and report.percent == 0.0
    assert [(a.written, a.found) for a in report.answers] == [(False, True)]
    assert "empty: YOUR ANSWER HERE" in report.format()
    path = edited(course, "lost.ipynb", None, None, drop_answer=True)
    report = exercises.grade(path)
    assert [(a.written, a.found, a.max_points) for a in report.answers] == [(False, False, 3)]
    assert "missing: answer cell deleted" in report.format()


def test_cli_json_reports_the_written_answers_and_the_percentage(course):
    path = edited(course, "half.ipynb", "def root(x):\n    return x / 2", "complex roots")
    out = subprocess.run([sys.executable, "-m", "minimanc", "grade", str(path), "--json"],
                         capture_output=True, text=True, cwd=ROOT, timeout=300)
    data = json.loads(out.stdout)
    assert out.returncode == 0
    assert data["total"] == 0 and data["max_total"] == 2 and data["percent"] == 0.0
    assert data["hand_max_total"] == 3
    assert data["to_grade_by_hand"] == [{"grade_id": "ex_a_w", "max_points": 3.0,
                                         "title": "Negative input", "written": True,
                                         "found": True}]
    assert data["rows"][0]["message"] == "AssertionError: x = 9: expected 3.0, got 4.5"
