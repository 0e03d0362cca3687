"""The notebook machinery: markers, exercise generation, grading, notebook hygiene."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import nbformat
import pytest

from minimanc import exercises
from minimanc.exercises import NotebookFormatError

ROOT = Path(__file__).resolve().parent.parent
FOLDERS = ("tutorials", "solutions", "exercises")


def notebooks(folder: str) -> list[Path]:
    return sorted((ROOT / folder).glob("*.ipynb"))


def solution_nb(cells: list[tuple[str, str, dict]]):
    """A notebook from (kind, source, nbgrader-metadata) triples."""
    nb = nbformat.v4.new_notebook()
    for kind, source, meta in cells:
        cell = (nbformat.v4.new_code_cell if kind == "code" else nbformat.v4.new_markdown_cell)(
            source
        )
        if meta:
            cell.metadata["nbgrader"] = meta
        nb.cells.append(cell)
    return nb


SOL = {"solution": True, "grade": False, "grade_id": "ex_a"}
GRADE = {"solution": False, "grade": True, "grade_id": "ex_a_tests", "points": 2}


# ------------------------------------------------------------------- stubs and markers
def test_stub_keeps_indentation_and_names_the_exercise():
    src = "def f(x):\n    y = 1\n    ### BEGIN SOLUTION\n    return x + y\n    ### END SOLUTION"
    out, top = exercises.stub_solution(src, "ex01_2", "Add one", "nb: cell 0")
    assert out == "def f(x):\n    y = 1\n    raise NotImplementedError('Exercise ex01_2: Add one')"
    assert top is False


def test_top_level_region_marks_the_cell_as_raising():
    nb = solution_nb([("code", "### BEGIN SOLUTION\nx = 1\n### END SOLUTION", SOL),
                      ("code", "assert x == 1\n### BEGIN HIDDEN TESTS\nassert x > 0\n"
                               "### END HIDDEN TESTS", GRADE)])
    ex = exercises.make_exercise(nb, "demo.ipynb")
    assert ex.cells[0].source == "raise NotImplementedError('Exercise ex_a')"
    assert "raises-exception" in ex.cells[0].metadata["tags"]
    assert ex.cells[1].source == "assert x == 1"
    assert "raises-exception" in ex.cells[1].metadata["tags"]
    # the solution notebook itself is untouched
    assert "x = 1" in nb.cells[0].source


@pytest.mark.parametrize(
    "source, meta, message",
    [
        ("### BEGIN SOLUTION\nx = 1", SOL, "unclosed '### BEGIN SOLUTION' at line 1"),
        ("### BEGIN SOLUTION\n### BEGIN SOLUTION\n### END SOLUTION\n### END SOLUTION", SOL,
         "nested"),
        ("x = 1\n### END SOLUTION", SOL,
         "'### END SOLUTION' at line 2 without '### BEGIN SOLUTION'"),
        ("### BEGIN SOLUTION\n### END HIDDEN TESTS", SOL,
         "mismatched '### END HIDDEN TESTS' at line 2"),
        ("### BEGIN SOLUTION\nx=1\n### END SOLUTION", {}, "not marked solution"),
        ("x = 1", SOL, "solution cell without"),
        ("### BEGIN HIDDEN TESTS\n### END HIDDEN TESTS", {}, "not a grade cell"),
    ],
)
def test_bad_markers_name_notebook_and_cell(source, meta, message):
    nb = solution_nb([("markdown", "intro", {}), ("code", source, meta)])
    with pytest.raises(NotebookFormatError) as info:
        exercises.make_exercise(nb, "broken.ipynb")
    assert "broken.ipynb: cell 1" in str(info.value)
    assert message in str(info.value)


def test_duplicate_grade_ids_are_refused():
    nb = solution_nb([("code", "### BEGIN SOLUTION\n### END SOLUTION", SOL),
                      ("code", "assert True", {**GRADE, "grade_id": "ex_a"})])
    with pytest.raises(NotebookFormatError, match=r"dup.ipynb: cell 1: duplicate grade_id 'ex_a'"):
        exercises.validate(nb, "dup.ipynb")


def test_grade_cell_needs_points():
    nb = solution_nb([("code", "assert True", {**GRADE, "points": 0})])
    with pytest.raises(NotebookFormatError, match="positive points"):
        exercises.validate(nb, "p.ipynb")


def test_percent_format_round_trip():
    text = (
        "# %% [markdown]\n# # Title\n#\n# text\n\n"
        "# %% tags=[\"NBVAL_IGNORE_OUTPUT\"]\nimport time\n\n"
        "# %% solution id=ex09_1 title=\"Forward pass\"\ndef f():\n"
        "    ### BEGIN SOLUTION\n    return 1\n    ### END SOLUTION\n\n"
        "# %% grade id=ex09_1_tests points=3\nassert f() == 1\n"
    )
    cells = exercises.cells_from_percent(text, "src.py")
    assert [c.cell_type for c in cells] == ["markdown", "code", "code", "code"]
    assert cells[0].source == "# Title\n\ntext"
    assert cells[1].metadata["tags"] == ["NBVAL_IGNORE_OUTPUT"]
    assert cells[2].metadata["nbgrader"]["grade_id"] == "ex09_1"
    assert cells[2].metadata["minimanc"]["title"] == "Forward pass"
    assert cells[3].metadata["nbgrader"]["points"] == 3


def test_percent_format_refuses_text_before_first_cell():
    with pytest.raises(NotebookFormatError, match="src.py: line 1"):
        exercises.cells_from_percent("x = 1\n# %%\n", "src.py")


# ------------------------------------------------------------------- the repository
def test_exercises_are_in_sync_with_solutions():
    stale = exercises.build(ROOT / "solutions", ROOT / "exercises", check=True)
    assert stale == [], f"run `minimanc exercises build`; stale: {stale}"


def test_every_chapter_has_all_three_notebooks():
    names = {folder: {p.name for p in notebooks(folder)} for folder in FOLDERS}
    assert names["tutorials"], "no tutorials"
    assert names["solutions"] == names["exercises"]
    assert names["solutions"] <= names["tutorials"], "a solutions notebook lacks its tutorial"


@pytest.mark.parametrize("folder", ["tutorials", "solutions"])
def test_every_code_cell_is_executed_with_outputs_stored(folder):
    """nbval never compares an unexecuted cell: a stripped notebook would pass vacuously."""
    problems = []
    for path in notebooks(folder):
        nb = nbformat.read(path, as_version=4)
        for index, cell in enumerate(nb.cells):
            if cell.cell_type != "code" or not cell.source.strip():
                continue
            if cell.execution_count is None:
                problems.append(f"{path.name}: cell {index} never executed")
            tags = cell.metadata.get("tags", [])
            errors = [o for o in cell.outputs if o.get("output_type") == "error"]
            if errors and "raises-exception" not in tags:
                problems.append(f"{path.name}: cell {index} stored an error")
    assert not problems, "\n".join(problems)


def test_solutions_grade_cells_pass_in_the_stored_run():
    """Each grade cell ran without error in the committed solutions (nbval re-checks)."""
    count = 0
    for path in notebooks("solutions"):
        nb = nbformat.read(path, as_version=4)
        for cell in nb.cells:
            if exercises.is_grade_cell(cell):
                count += 1
                assert cell.execution_count is not None, exercises.grade_id(cell)
                assert not [o for o in cell.outputs if o.get("output_type") == "error"]
    assert count > 0


ADDRESS = re.compile(r"at 0x[0-9a-fA-F]{6,}")
MACHINE_PATH = re.compile(r"(/work/|/root/|/home/|/tmp/|site-packages)")


@pytest.mark.parametrize("folder", ["tutorials", "solutions"])
def test_no_machine_paths_or_memory_addresses_in_outputs(folder):
    problems = []
    for path in notebooks(folder):
        nb = nbformat.read(path, as_version=4)
        for index, cell in enumerate(nb.cells):
            for output in cell.get("outputs", []):
                text = json.dumps({k: v for k, v in output.get("data", {}).items()
                                   if k.startswith("text")})
                text += output.get("text", "") if isinstance(output.get("text"), str) else ""
                if ADDRESS.search(text) or MACHINE_PATH.search(text):
                    problems.append(f"{path.name}: cell {index}")
    assert not problems, problems


@pytest.mark.whole_run
def test_every_grade_cell_fails_on_its_stub():
    """Run each exercise notebook: every grade cell must fail on the generated stubs."""
    checked = 0
    for path in notebooks("exercises"):
        report = exercises.grade(path, timeout=600)
        assert report.rows, f"{path.name}: no grade cells"
        for row in report.rows:
            checked += 1
            assert row.points == 0, f"{path.name}: {row.grade_id} passes on the stub"
            assert "NotImplementedError" in row.message, (path.name, row.grade_id, row.message)
    assert checked > 0


@pytest.mark.whole_run
@pytest.mark.parametrize("path", notebooks("solutions"), ids=lambda p: p.stem)
def test_every_solution_scores_full_marks_when_graded(path):
    """The reference solutions pass their own tests under the grader, with the
    library functions each exercise forbids switched off."""
    report = exercises.grade(path, source=path, timeout=600)
    failed = [(r.grade_id, r.message) for r in report.rows if r.points != r.max_points]
    assert report.rows and not failed, failed


# ------------------------------------------------------------------- grading robustness
def make_student_nb(tmp_path: Path, grade_sources: list[str], answer: str = "x = 1"):
    sol = solution_nb(
        [("code", f"### BEGIN SOLUTION\n{answer}\n### END SOLUTION", SOL)]
        + [("code", src, {**GRADE, "grade_id": f"t{i}", "points": 1})
           for i, src in enumerate(grade_sources)]
    )
    (tmp_path / "solutions").mkdir()
    (tmp_path / "exercises").mkdir()
    nbformat.write(sol, tmp_path / "solutions" / "hw.ipynb")
    exercises.build(tmp_path / "solutions", tmp_path / "exercises")
    return tmp_path / "exercises" / "hw.ipynb"


def answer(path: Path, code: str):
    nb = nbformat.read(path, as_version=4)
    nb.cells[0].source = code
    nbformat.write(nb, path)
    return nb


def test_grade_uses_hidden_tests_and_survives_moved_deleted_duplicated_cells(tmp_path):
    path = make_student_nb(
        tmp_path,
        ["assert x >= 1\n### BEGIN HIDDEN TESTS\nassert x == 1\n### END HIDDEN TESTS",
         "assert x > 0", "assert isinstance(x, int)"],
    )
    nb = answer(path, "x = 2")  # passes visible tests only
    grade_cells = nb.cells[1:]
    # move t2 first, duplicate t1, delete nothing yet; student edits t0's asserts away
    grade_cells[0].source = "pass"
    nb.cells = [nb.cells[0], grade_cells[2], grade_cells[0], grade_cells[1], grade_cells[1]]
    nbformat.write(nb, path)
    report = exercises.grade(path)
    rows = {r.grade_id: r for r in report.rows}
    assert rows["t0"].points == 0 and "AssertionError" in rows["t0"].message  # hidden test
    assert rows["t1"].points == 1 and rows["t2"].points == 1
    assert any("duplicated" in n for n in report.notes)
    # delete t1 entirely
    nb.cells = [c for c in nb.cells if exercises.grade_id(c) != "t1"]
    nbformat.write(nb, path)
    report = exercises.grade(path)
    rows = {r.grade_id: r for r in report.rows}
    assert rows["t1"].points == 0 and rows["t1"].message.startswith("missing")
    assert report.max_total == 3


def test_grade_times_out_an_infinite_loop(tmp_path):
    path = make_student_nb(tmp_path, ["assert x == 1"])
    answer(path, "while True:\n    pass")
    report = exercises.grade(path, timeout=3)
    assert report.total == 0
    assert "stopped: timeout after 3 s" in " ".join(report.notes)
    assert "KeyboardInterrupt" not in report.format()


def test_grade_reports_a_kernel_crash(tmp_path):
    path = make_student_nb(tmp_path, ["assert x == 1"])
    answer(path, "import os\nos._exit(1)")
    report = exercises.grade(path, timeout=30)
    assert report.total == 0
    assert "kernel died" in " ".join(report.notes) + report.rows[0].message


def test_grade_refuses_an_unreadable_notebook(tmp_path):
    bad = tmp_path / "bad.ipynb"
    bad.write_text("{ not json")
    with pytest.raises(exercises.GradeRefused, match="bad.ipynb is not valid JSON"):
        exercises.grade(bad)


# ------------------------------------------------------------------- the command
def run_cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "minimanc", *args], capture_output=True,
                          text=True, cwd=ROOT, timeout=300)


def test_cli_version_and_info():
    assert run_cli("--version").stdout.startswith("minimanc ")
    info = run_cli("info")
    assert info.returncode == 0 and "00 overview" in info.stdout and "jax" in info.stdout


def test_cli_grade_json(tmp_path):
    path = make_student_nb(tmp_path, ["assert x == 1"])
    out = run_cli("grade", str(path), "--json")
    data = json.loads(out.stdout)
    assert data["total"] == 0 and data["max_total"] == 1


def test_cli_build_check_detects_a_stale_exercise(tmp_path):
    path = make_student_nb(tmp_path, ["assert x == 1"])
    assert exercises.build(tmp_path / "solutions", tmp_path / "exercises", check=True) == []
    answer(path, "x = 1  # edited by hand")
    assert exercises.build(tmp_path / "solutions", tmp_path / "exercises", check=True) == [
        "hw.ipynb"
    ]
