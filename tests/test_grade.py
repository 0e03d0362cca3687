"""The grader cannot be fooled and fails loudly.

Grading starts a kernel per notebook, so these tests use tiny synthetic
notebooks written in the percent format; one test grades a real chapter.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
import types
from pathlib import Path

import nbformat
import numpy as np
import pytest

from minimanc import dmp, exercises

ROOT = Path(__file__).resolve().parent.parent

HW = '''# %%
from minimanc import dmp

# %% solution id=ex_a title="Classify" forbids="minimanc.dmp.classify"
def classify(a, b):
    ### BEGIN SOLUTION
    return "underdamped" if a < 4 * b else "overdamped"
    ### END SOLUTION

# %% grade id=ex_a_tests points=2
assert classify(1.0, 1.0) == "underdamped", "visible: underdamped"
### BEGIN HIDDEN TESTS
assert classify(16.0, 1.0) == "overdamped", "hidden: overdamped"
### END HIDDEN TESTS

# %% solution id=ex_b title="Double"
def double(x):
    ### BEGIN SOLUTION
    return 2 * x
    ### END SOLUTION

# %% grade id=ex_b_tests points=3
assert double(2) == 4

# %%
after = dmp.classify(1.0, 1.0)   # the library again, after the grade cells
print(after)
'''


@pytest.fixture(scope="module")
def course(tmp_path_factory) -> Path:
    """A course folder with solutions/hw.ipynb (executed) and exercises/hw.ipynb."""
    root = tmp_path_factory.mktemp("course")
    (root / "hw_solutions.py").write_text(HW)
    exercises.convert(root / "hw_solutions.py", root / "solutions" / "hw.ipynb")
    exercises.build(root / "solutions", root / "exercises")
    return root


def student(course: Path, name: str, answers: dict[str, str], folder: Path | None = None):
    """A copy of exercises/hw.ipynb at ``folder/name`` with solution cells replaced."""
    nb = nbformat.read(course / "exercises" / "hw.ipynb", as_version=4)
    for cell in nb.cells:
        gid = exercises.grade_id(cell)
        if exercises.is_solution_cell(cell) and gid in answers:
            cell.source = answers[gid]
    target = (folder or course / "exercises") / name
    target.parent.mkdir(parents=True, exist_ok=True)
    nbformat.write(nb, target)
    return target


GOOD = {"ex_a": 'def classify(a, b):\n    return "underdamped" if a < 4 * b else "overdamped"',
        "ex_b": "def double(x):\n    return x + x"}


def rows(report) -> dict:
    return {r.grade_id: r for r in report.rows}


def run_cli(*args: str, cwd: Path = ROOT) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "minimanc", *args], capture_output=True,
                          text=True, cwd=cwd, timeout=300)


# ------------------------------------------------------------ identity of the assignment
def test_build_writes_the_assignment_and_the_tests_fingerprint(course):
    sol = nbformat.read(course / "solutions" / "hw.ipynb", as_version=4)
    ex = nbformat.read(course / "exercises" / "hw.ipynb", as_version=4)
    assert sol.metadata["minimanc"] == {"assignment": "hw"}
    assert ex.metadata["minimanc"]["assignment"] == "hw"
    assert ex.metadata["minimanc"]["source_sha256"] == exercises.source_fingerprint(sol)
    forbids = [c.metadata["minimanc"].get("forbids") for c in sol.cells
               if exercises.is_solution_cell(c)]
    assert forbids == [["minimanc.dmp.classify"], None]


def test_a_renamed_copy_with_edited_grade_cells_is_graded_against_solutions(course):
    path = student(course, "hw-Copy1.ipynb", {"ex_a": GOOD["ex_a"], "ex_b": "double = None"})
    nb = nbformat.read(path, as_version=4)
    for cell in nb.cells:
        if exercises.is_grade_cell(cell):
            cell.source = "pass"          # the student "fixes" the tests
    nbformat.write(nb, path)
    report = exercises.grade(path)
    assert report.assignment == "hw" and report.source.endswith("hw.ipynb")
    got = rows(report)
    assert got["ex_a_tests"].points == 2
    assert got["ex_b_tests"].points == 0 and "TypeError" in got["ex_b_tests"].message
    assert report.max_total == 5


def test_a_notebook_outside_the_course_is_found_through_its_metadata(course, tmp_path):
    path = student(course, "mine.ipynb", GOOD, folder=tmp_path / "home")
    with pytest.raises(exercises.GradeRefused, match="no solutions notebook for assignment 'hw'"):
        exercises.grade(path)
    report = exercises.grade(path, roots=[course])
    assert report.total == report.max_total == 5


def test_a_notebook_without_metadata_is_refused(course, tmp_path):
    path = student(course, "hw.ipynb", GOOD, folder=tmp_path / "exercises")
    nb = nbformat.read(path, as_version=4)
    del nb.metadata["minimanc"]
    nbformat.write(nb, path)
    (tmp_path / "solutions").mkdir()
    shutil.copy(course / "solutions" / "hw.ipynb", tmp_path / "solutions")  # same file name
    out = run_cli("grade", str(path))
    assert out.returncode == 2 and out.stdout == ""
    assert out.stderr.count("\n") == 1 and "cannot tell which assignment" in out.stderr
    assert "--source" in out.stderr
    report = exercises.grade(path, source=course / "solutions" / "hw.ipynb")
    assert report.total == 5


def test_a_source_of_another_assignment_is_refused(course, tmp_path):
    other = tmp_path / "other.ipynb"
    nb = nbformat.read(course / "solutions" / "hw.ipynb", as_version=4)
    nb.metadata["minimanc"] = {"assignment": "other"}
    nbformat.write(nb, other)
    with pytest.raises(exercises.GradeRefused, match="is assignment 'hw' but --source"):
        exercises.grade(course / "exercises" / "hw.ipynb", source=other)


def test_metadata_cannot_point_outside_solutions(course, tmp_path):
    path = student(course, "x.ipynb", GOOD, folder=tmp_path)
    nb = nbformat.read(path, as_version=4)
    nb.metadata["minimanc"]["assignment"] = "../exercises/x"
    nbformat.write(nb, path)
    with pytest.raises(exercises.GradeRefused, match="cannot tell which assignment"):
        exercises.grade(path, roots=[course])


def test_a_grade_cell_without_its_metadata_scores_zero_and_is_listed(course):
    path = student(course, "nometa.ipynb", GOOD)
    nb = nbformat.read(path, as_version=4)
    for cell in nb.cells:
        if exercises.grade_id(cell) == "ex_b_tests":
            del cell.metadata["nbgrader"]
    nbformat.write(nb, path)
    report = exercises.grade(path)
    got = rows(report)
    assert list(got) == ["ex_a_tests", "ex_b_tests"] and report.max_total == 5
    assert got["ex_b_tests"].points == 0 and got["ex_b_tests"].message.startswith("missing")
    assert "ex_b_tests" in report.format() and "total 2/5" in report.format()


def test_a_changed_source_is_noted(course, tmp_path):
    path = student(course, "old.ipynb", GOOD)
    nb = nbformat.read(path, as_version=4)
    nb.metadata["minimanc"]["source_sha256"] = "0" * 64
    nbformat.write(nb, path)
    assert any("tests changed" in n for n in exercises.grade(path).notes)


# ------------------------------------------------------------------ labelled failures
def test_hidden_and_visible_failures_are_labelled(course):
    hidden = student(course, "hidden.ipynb", {"ex_a": "def classify(a, b):\n"
                                                      "    return 'underdamped'"})
    row = rows(exercises.grade(hidden))["ex_a_tests"]
    assert row.hidden and row.message == "hidden test failed: AssertionError: hidden: overdamped"
    visible = student(course, "visible.ipynb", {"ex_a": "def classify(a, b):\n"
                                                        "    return 'overdamped'"})
    row = rows(exercises.grade(visible))["ex_a_tests"]
    assert not row.hidden and row.message == "AssertionError: visible: underdamped"


def test_a_grade_cell_that_runs_too_long_says_timeout(course):
    path = student(course, "slow.ipynb", {
        "ex_a": GOOD["ex_a"], "ex_b": "def double(x):\n    while True:\n        pass"})
    # the timeout holds for every cell, the notebook's imports too: 20 s leaves them room on a
    # loaded machine (3 s did not, at a load of 10 on 2 cores)
    report = exercises.grade(path, timeout=20)
    got = rows(report)
    assert got["ex_b_tests"].message == "timeout after 20 s"
    assert got["ex_a_tests"].points == 2
    assert "KeyboardInterrupt" not in report.format()


def test_a_swallowed_exception_does_not_pass(course):
    path = student(course, "swallow.ipynb", {
        "ex_a": "get_ipython().set_custom_exc((BaseException,), lambda *a, **k: None)\n"
                "def classify(a, b):\n    return 'nonsense'"})
    assert rows(exercises.grade(path))["ex_a_tests"].points == 0


BROKEN_SETUP = '''# %%
import builtins

IN_TESTS = not hasattr(builtins, "get_ipython")   # the tests' process, not a kernel

# %%
if IN_TESTS:
    raise RuntimeError("the setup broke")

# %% solution id=ex_a title="One"
def one():
    ### BEGIN SOLUTION
    return 1
    ### END SOLUTION

# %% grade id=ex_a_tests points=1
assert one() == 1

# %%
while IN_TESTS:
    pass

# %% solution id=ex_b title="Two"
def two():
    ### BEGIN SOLUTION
    return 2
    ### END SOLUTION

# %% grade id=ex_b_tests points=1
assert two() == 2
'''


def test_a_setup_that_fails_or_hangs_in_the_tests_process_is_reported(tmp_path):
    """The solutions notebook's own cells run again in the tests' process: one that fails
    there is named in a note, one that never ends stops only the grade cells after it."""
    (tmp_path / "broken_solutions.py").write_text(BROKEN_SETUP)
    exercises.convert(tmp_path / "broken_solutions.py", tmp_path / "solutions" / "broken.ipynb")
    exercises.build(tmp_path / "solutions", tmp_path / "exercises")
    solutions = nbformat.read(tmp_path / "solutions" / "broken.ipynb", as_version=4)
    nb = nbformat.read(tmp_path / "exercises" / "broken.ipynb", as_version=4)
    for mine, ref in zip(nb.cells, solutions.cells):
        if exercises.is_solution_cell(mine):
            mine.source = ref.source
    nbformat.write(nb, tmp_path / "exercises" / "broken.ipynb")
    report = exercises.grade(tmp_path / "exercises" / "broken.ipynb", timeout=15)
    got = rows(report)
    assert got["ex_a_tests"].points == 1
    assert got["ex_b_tests"].points == 0
    assert got["ex_b_tests"].message == ("not run: the tests' process stalled: no progress in "
                                         "15 s")
    assert any("the tests' own setup failed (cell 1: RuntimeError: the setup broke)" in n
               for n in report.notes), report.notes


# ------------------------------------------------------------------ library shadowing
@pytest.mark.parametrize("code", [
    "classify = dmp.classify",
    "from minimanc.dmp import classify",
    "def classify(*a):\n    return dmp.classify(*a)",
    "import types\nclassify = types.FunctionType(dmp.classify.__code__, dmp.classify.__globals__)",
], ids=["alias", "from-import", "wrapper", "copy"])
def test_delegating_to_the_library_scores_zero(course, code):
    path = student(course, "delegate.ipynb", {"ex_a": code, "ex_b": GOOD["ex_b"]})
    report = exercises.grade(path)
    got = rows(report)
    assert got["ex_a_tests"].points == 0
    assert got["ex_a_tests"].message == (
        "ForbiddenFunctionError: Exercise ex_a: write classify yourself; "
        "minimanc.dmp.classify is disabled while grading")
    assert got["ex_b_tests"].points == 3  # restored for the rest of the notebook


def test_shadow_blocks_every_reference_and_restores():
    from minimanc.dmp import classify as bound
    wrapper = lambda a, b: dmp.classify(a, b)  # noqa: E731
    namespace = {"bound": bound, "wrapper": wrapper}
    guard = exercises.shadow(["minimanc.dmp.classify", "minimanc.dmp.no_such_name"], "ex9",
                             namespace)
    for call in (dmp.classify, bound, namespace["bound"], wrapper):
        with pytest.raises(exercises.ForbiddenFunctionError, match="Exercise ex9: write classify"):
            call(1.0, 1.0)
    guard.restore()
    guard.restore()
    assert bound(1.0, 1.0) == wrapper(1.0, 1.0) == "underdamped"


def test_shadow_handles_closures_and_non_function_callables():
    module = types.ModuleType("minimanc_fake_lib")
    k = 3

    def closure(x):
        return x * k

    module.closure = closure
    module.ufunc = np.add
    sys.modules["minimanc_fake_lib"] = module
    try:
        namespace = {"mine": np.add}
        guard = exercises.shadow(["minimanc_fake_lib.closure", "minimanc_fake_lib.ufunc"], "e",
                                 namespace)
        with pytest.raises(exercises.ForbiddenFunctionError):
            closure(2)
        with pytest.raises(exercises.ForbiddenFunctionError):
            module.ufunc(1, 2)
        with pytest.raises(exercises.ForbiddenFunctionError):
            namespace["mine"](1, 2)
        guard.restore()
        assert closure(2) == 6 and module.ufunc is np.add and namespace["mine"] is np.add
    finally:
        del sys.modules["minimanc_fake_lib"]


def test_forbids_must_be_dotted_names():
    text = ('# %% solution id=ex1 forbids="classify"\n### BEGIN SOLUTION\nx = 1\n'
            '### END SOLUTION\n')
    nb = nbformat.v4.new_notebook()
    nb.cells = exercises.cells_from_percent(text, "s.py")
    with pytest.raises(exercises.NotebookFormatError, match="forbids must list dotted names"):
        exercises.validate(nb, "s.ipynb")
    text = text.replace('"classify"', '["minimanc.dmp.classify", "minimanc.dmp.step"]')
    cells = exercises.cells_from_percent(text, "s.py")
    assert cells[0].metadata["minimanc"]["forbids"] == ["minimanc.dmp.classify",
                                                        "minimanc.dmp.step"]


def test_every_forbidden_function_of_the_course_exists():
    for path in sorted((ROOT / "solutions").glob("*.ipynb")):
        nb = nbformat.read(path, as_version=4)
        for exercise, targets in exercises.forbidden_functions(nb).items():
            for dotted in targets:
                owner, name, value = exercises.resolve(dotted)
                assert callable(value), (path.name, exercise, dotted)


# ------------------------------------------------------------------ the command line
@pytest.mark.parametrize("kind", ["missing", "directory", "invalid-json", "binary", "not-nb"])
def test_cli_refuses_what_is_not_a_notebook_with_one_line_and_exit_2(tmp_path, kind):
    path = tmp_path / "nb.ipynb"
    if kind == "directory":
        path.mkdir()
    elif kind == "invalid-json":
        path.write_text('{"cells": [')
    elif kind == "binary":
        path.write_bytes(bytes(range(256)) * 4)
    elif kind == "not-nb":
        path.write_text("[1, 2]")
    out = run_cli("grade", str(path))
    assert out.returncode == 2, out
    assert out.stdout == "" and out.stderr.count("\n") == 1, out.stderr
    assert out.stderr.startswith("minimanc grade: error: ") and "Traceback" not in out.stderr
    assert "nb.ipynb" in out.stderr


def test_cli_bad_source_is_one_line(course, tmp_path):
    out = run_cli("grade", str(course / "exercises" / "hw.ipynb"), "--source",
                  str(tmp_path / "nope.ipynb"))
    assert out.returncode == 2 and out.stderr.count("\n") == 1
    assert "--source" in out.stderr and "no such file" in out.stderr


def test_cli_fail_under_and_quiet_kernel(course):
    path = student(course, "partial.ipynb", {"ex_a": GOOD["ex_a"]})   # 2 of 5 points
    out = run_cli("grade", str(path), "--fail-under", "2")
    assert out.returncode == 0 and "total 2/5" in out.stdout
    assert "IPKernelApp" not in out.stderr and "TCP" not in out.stderr, out.stderr
    out = run_cli("grade", str(path), "--fail-under", "50%", "--json")
    assert out.returncode == 1 and '"total": 2.0' in out.stdout
    assert "below --fail-under 50%" in out.stderr
    bad = run_cli("grade", str(path), "--fail-under", "lots")
    assert bad.returncode == 2 and bad.stderr.count("\n") == 1 and "--fail-under" in bad.stderr


def test_cli_exercises_without_an_action_names_only_the_action():
    out = run_cli("exercises")
    assert out.returncode == 2
    assert "required: {build,convert,run}" in out.stderr and "paths" not in out.stderr


# ------------------------------------------------------------------ a real chapter
def test_chapter_3_boundary_mistakes_fail_the_hidden_tests(tmp_path):
    """A renamed copy outside the course: ``h*beta > 1`` loses the hidden tests, a
    ``gains_for`` without its overdamped branch loses 3.1's second grade cell,
    ``dmp.max_stable_alpha`` is refused, a correct implicit Euler step passes."""
    nb = nbformat.read(ROOT / "exercises" / "03_dmp.ipynb", as_version=4)
    answers = {
        "ex03_1": "def gains_for(zeta, t_settle):\n"
                  "    omega = 4.0 / (t_settle * zeta)\n"
                  "    return 2.0 * zeta * omega, omega / (2.0 * zeta)",
        "ex03_2": "def implicit_euler_step(y, dy, goal, alpha, beta, h):\n"
                  "    dy_next = (dy + h * alpha * beta * (goal - y))"
                  " / (1.0 + h * alpha + h * h * alpha * beta)\n"
                  "    return y + h * dy_next, dy_next",
        "ex03_3": "def max_stable_alpha_euler(beta, h):\n"
                  "    if h * beta > 1.0:\n        return 0.0\n"
                  "    return 4.0 / (h * (2.0 - h * beta))",
    }
    for cell in nb.cells:
        if exercises.is_solution_cell(cell):
            cell.source = answers.get(exercises.grade_id(cell), cell.source)
    path = tmp_path / "03_dmp-Copy1.ipynb"
    nbformat.write(nb, path)
    report = exercises.grade(path, roots=[ROOT])
    got = rows(report)
    assert report.source == str(ROOT / "solutions" / "03_dmp.ipynb")
    assert got["ex03_1_zeta_tests"].points == got["ex03_1_zeta_tests"].max_points
    assert got["ex03_1_tests"].points == 0 and "(10, 1.6)" in got["ex03_1_tests"].message
    assert got["ex03_2_tests"].points == got["ex03_2_tests"].max_points
    assert got["ex03_3_tests"].hidden and "h*beta = 1" in got["ex03_3_tests"].message
    for cell in nb.cells:
        if exercises.grade_id(cell) == "ex03_3":
            cell.source = ("def max_stable_alpha_euler(beta, h):\n"
                           "    return dmp.max_stable_alpha(beta, h, 'euler', 1)")
    nbformat.write(nb, path)
    row = rows(exercises.grade(path, roots=[ROOT]))["ex03_3_tests"]
    assert row.points == 0 and "disabled while grading" in row.message


@pytest.mark.parametrize("source, labelled", [
    ("def f():\n    return 1\nassert f() == 1", True),
    ("for i in range(3):\n    ### BEGIN HIDDEN TESTS\n    assert i < 3\n    ### END HIDDEN TESTS\n"
     "    assert i >= 0", True),
    ("if True:\n    x = 1\n  ### BEGIN HIDDEN TESTS\n    assert x\n### END HIDDEN TESTS", False),
])
def test_instrumented_grade_cells_stay_valid_python(source, labelled):
    import ast

    out, ok = exercises.instrument_grade_source(source)
    ast.parse(out)
    assert ok is labelled and out.startswith('_minimanc_grading_part = "visible"\n')
    assert ('_minimanc_grading_part = "hidden"' in out) is (labelled and "HIDDEN" in source)
