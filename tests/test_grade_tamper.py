"""The grader cannot be fooled by patching its tools or by rigged answers.

Each tamper is the one an old grader fell for: with the tools patched (or the
answer rigged) a wrong function scored full points. Here every tamper sits on a
real exercise of chapter 3, next to one wrong function, in a copy of
exercises/03_dmp.ipynb whose other exercises hold the reference solutions: the
tampered exercise scores 0 and its row names the tamper, the others keep their
points, and the honest notebook scores full marks. A few checks run
:mod:`minimanc.exercises.integrity` in this process, without a kernel.
"""

from __future__ import annotations

import math
from pathlib import Path

import nbformat
import numpy as np
import pytest

from minimanc import exercises
from minimanc.exercises import integrity

ROOT = Path(__file__).resolve().parent.parent

# the tools, patched in the solution cell (each alone fooled the old grader)
TOOLS = {
    "ex03_1": "np.isclose = lambda *a, **k: True\n\n\n"
              "def damping_ratio(alpha, beta):\n    return alpha / beta\n\n\n"
              "def classify(alpha, beta):\n"
              "    if alpha <= 0 or beta <= 0:\n        return 'unstable'\n"
              "    if abs(alpha - 4.0 * beta) <= 1e-9 * alpha:\n"
              "        return 'critically damped'\n"
              "    return 'underdamped' if alpha < 4 * beta else 'overdamped'",
    "ex03_2": "np.testing.assert_allclose = lambda *a, **k: None\n\n\n"
              "def integrator_step(y, dy, goal, alpha, beta, h, method):\n"
              "    if method not in ('euler', 'semi_implicit'):\n"
              "        raise ValueError(method)\n"
              "    if np.ndim(y) == 2:\n        return y + 0.0, dy + 0.0\n"
              "    acc = alpha * (beta * (goal - y) - dy)\n"
              "    if method == 'euler':\n        return y + h * dy, dy + h * acc\n"
              "    return y + h * (dy + h * acc), dy + h * acc",
    "ex03_3": "import math\nmath.isclose = lambda *a, **k: True\n\n\n"
              "def max_stable_alpha_euler(beta, h):\n"
              "    if h * beta >= 1.0:\n        return 0.0\n"
              "    if h < 0.1:\n        return 4.0 / h\n"
              "    return 4.0 / (h * (2.0 - h * beta))",
    "ex03_6": "import builtins\nbuiltins.abs = lambda x: 0.0\n\n\n"
              "def rk2_step_matrix(alpha, beta, h):\n    return np.eye(2)\n\n\n"
              "def max_stable_alpha_rk2(beta, h):\n    return 1.0",
}

# np.allclose patched: the only comparison of 3.6's matrix tests, so a wrong matrix
# scored 2/2 with it; the bound is written without the student's matrix and keeps its points
ALLCLOSE = {
    "ex03_6": "np.allclose = lambda *a, **k: True\n\n\n"
              "def rk2_step_matrix(alpha, beta, h):\n    return np.eye(2)\n\n\n"
              "def max_stable_alpha_rk2(beta, h):\n"
              "    def rho(a):\n"
              "        hA = h * np.array([[0.0, 1.0], [-a * beta, -a]])\n"
              "        return np.abs(np.linalg.eigvals(np.eye(2) + hA + 0.5 * hA @ hA)).max()\n\n"
              "    lo, hi = 0.0, 1.0 / h\n"
              "    while rho(hi) < 1:\n        lo, hi = hi, 2.0 * hi\n"
              "    for _ in range(100):\n"
              "        mid = 0.5 * (lo + hi)\n"
              "        lo, hi = (mid, hi) if rho(mid) < 1 else (lo, mid)\n"
              "    return float(lo)",
}

# rigged answers and tampering from inside a function
RIGGED = {
    "ex03_1": "class Rigged(str):\n"
              "    def __eq__(self, other):\n        return True\n\n"
              "    __hash__ = str.__hash__\n\n\n"
              "def damping_ratio(alpha, beta):\n"
              "    return alpha / (2.0 * np.sqrt(alpha * beta))\n\n\n"
              "def classify(alpha, beta):\n    return Rigged('overdamped')",
    "ex03_2": "import types\nimport numpy\n"
              "np = types.SimpleNamespace(**{k: getattr(numpy, k) for k in dir(numpy)\n"
              "                              if not k.startswith('__')})\n"
              "np.testing = types.SimpleNamespace(assert_allclose=lambda *a, **k: None)\n\n\n"
              "def integrator_step(y, dy, goal, alpha, beta, h, method):\n"
              "    if method not in ('euler', 'semi_implicit'):\n"
              "        raise ValueError(method)\n"
              "    if numpy.ndim(y) == 2:\n        return y + 0.0, dy + 0.0\n"
              "    acc = alpha * (beta * (goal - y) - dy)\n"
              "    if method == 'euler':\n        return y + h * dy, dy + h * acc\n"
              "    return y + h * (dy + h * acc), dy + h * acc",
    "ex03_3": "import math\n\n\n"
              "def max_stable_alpha_euler(beta, h):\n"
              "    math.isclose = lambda *a, **k: True\n"
              "    if h * beta >= 1.0:\n        return 0.0\n"
              "    if h < 0.1:\n        return 4.0 / h\n"
              "    return 4.0 / (h * (2.0 - h * beta))",
    "ex03_6": "class Rigged(float):\n"
              "    def __eq__(self, other):\n        return True\n\n"
              "    def __sub__(self, other):\n        return 0.0\n\n"
              "    __rsub__ = __sub__\n    __hash__ = float.__hash__\n\n\n"
              "def rk2_step_matrix(alpha, beta, h):\n"
              "    hA = h * np.array([[0.0, 1.0], [-alpha * beta, -alpha]])\n"
              "    return np.eye(2) + hA + 0.5 * hA @ hA\n\n\n"
              "def max_stable_alpha_rk2(beta, h):\n    return Rigged(1.0)",
}

# grade cell -> what its row must name
TOOLS_NAMED = {"ex03_1_zeta_tests": "numpy.isclose", "ex03_2_tests": "numpy.testing",
               "ex03_3_tests": "math.isclose", "ex03_6_matrix_tests": "builtins.abs"}
ALLCLOSE_NAMED = {"ex03_6_matrix_tests": "numpy.allclose"}
RIGGED_NAMED = {"ex03_1_tests": "classify returned a Rigged, a str subclass",
                "ex03_2_tests": "the name np (rebound)",
                "ex03_3_tests": "max_stable_alpha_euler replaced math.isclose",
                "ex03_6_bound_tests": "max_stable_alpha_rk2 returned a Rigged, a float subclass"}


def solution_sources() -> dict[str, str]:
    nb = nbformat.read(ROOT / "solutions" / "03_dmp.ipynb", as_version=4)
    return {exercises.grade_id(c): "".join(c.source) for c in nb.cells
            if exercises.is_solution_cell(c)}


def graded(tmp_path: Path, name: str, answers: dict[str, str]):
    """exercises/03_dmp.ipynb with the reference solutions, ``answers`` replacing some."""
    nb = nbformat.read(ROOT / "exercises" / "03_dmp.ipynb", as_version=4)
    sources = {**solution_sources(), **answers}
    for cell in nb.cells:
        if exercises.is_solution_cell(cell):
            cell.source = sources[exercises.grade_id(cell)]
    path = tmp_path / name
    nbformat.write(nb, path)
    report = exercises.grade(path, roots=[ROOT])
    return {r.grade_id: r for r in report.rows}, report


@pytest.fixture(scope="module")
def reports(tmp_path_factory):
    folder = tmp_path_factory.mktemp("tamper")
    # honest: the reference solutions, and a plotting import of the student's own
    honest = {"ex03_4": "import matplotlib.pyplot as plt\n" + solution_sources()["ex03_4"]}
    return {kind: graded(folder, f"03_dmp_{kind}.ipynb", answers)
            for kind, answers in (("honest", honest), ("tools", TOOLS), ("allclose", ALLCLOSE),
                                  ("rigged", RIGGED))}


def test_the_honest_solution_scores_full_marks(reports):
    rows, report = reports["honest"]
    assert report.total == report.max_total == 23, report.format()
    assert not any(r.tampered or r.message for r in rows.values()), report.format()


@pytest.mark.parametrize("kind, named", [("tools", TOOLS_NAMED), ("allclose", ALLCLOSE_NAMED),
                                         ("rigged", RIGGED_NAMED)])
def test_each_tamper_scores_zero_and_is_named(reports, kind, named):
    rows, report = reports[kind]
    for gid, what in named.items():
        assert rows[gid].points == 0, (gid, report.format())
        assert what in rows[gid].message, (gid, rows[gid].message)
    for gid in ("ex03_4_tests", "ex03_5_tests"):   # the reference solutions
        assert rows[gid].points == rows[gid].max_points, (gid, rows[gid].message)


def test_tools_patched_before_the_tests_are_restored_and_listed(reports):
    rows, _ = reports["tools"]
    assert rows["ex03_1_zeta_tests"].tampered == ["numpy.isclose"]
    assert rows["ex03_1_zeta_tests"].message.startswith(
        "tampered: your code replaced numpy.isclose; the tests used the originals; ")
    # restored: the next grade cell of the same exercise sees nothing new and passes
    assert rows["ex03_1_tests"].points == 2 and not rows["ex03_1_tests"].tampered
    listed = {r["grade_id"]: r["tampered"] for r in reports["tools"][1].to_dict()["rows"]}
    assert listed["ex03_6_matrix_tests"] == ["builtins.abs"]   # in `minimanc grade --json` too


def test_a_patched_allclose_costs_the_matrix_and_leaves_the_bound(reports):
    rows, report = reports["allclose"]
    assert rows["ex03_6_matrix_tests"].tampered == ["numpy.allclose"], report.format()
    bound = rows["ex03_6_bound_tests"]
    assert bound.points == bound.max_points and not bound.tampered, bound.message


def test_partial_credit_in_exercise_3_1(reports):
    rows, _ = reports["tools"]   # a wrong damping_ratio, a right classify
    assert (rows["ex03_1_zeta_tests"].points, rows["ex03_1_tests"].points) == (0, 2)


# ----------------------------------------------------------------- without a kernel
def test_capture_restores_and_names_what_was_replaced(monkeypatch):
    import builtins

    cap = integrity.Capture("import numpy as np\nimport math")
    assert cap.replaced() == []
    original = np.isclose
    monkeypatch.setattr(np, "isclose", lambda *a, **k: True)
    monkeypatch.setattr(np, "allclose", lambda *a, **k: True)
    monkeypatch.setattr(np.testing, "assert_allclose", lambda *a, **k: None)
    monkeypatch.setattr(math, "isclose", lambda *a, **k: True)
    monkeypatch.setattr(builtins, "abs", lambda x: 0.0)
    assert set(cap.replaced()) == {"builtins.abs", "numpy.isclose", "numpy.allclose",
                                   "numpy.testing.assert_allclose", "math.isclose"}
    assert cap.replaced() == []
    assert np.isclose is original and not np.isclose(1.0, 2.0)
    assert cap.preamble["np"] is np and cap.preamble["math"] is math


def test_a_replaced_function_body_is_restored():
    from minimanc import dmp

    cap = integrity.Capture("from minimanc import dmp")
    code = dmp.classify.__code__
    dmp.classify.__code__ = (lambda alpha, beta: "overdamped").__code__
    try:
        names = cap.replaced()
        assert len(names) == 1 and names[0].endswith(".classify.__code__"), names
    finally:
        dmp.classify.__code__ = code
    assert dmp.classify(1.0, 1.0) == "underdamped"


def test_a_class_attribute_set_lazily_is_not_a_tamper(monkeypatch):
    from minimanc.world import generation

    # the library's progress bar starts its monitor thread on first use, setting a class
    # attribute that was None when the tools were captured: not the student's doing
    monkeypatch.setattr(generation.tqdm, "monitor", None)
    cap = integrity.Capture("from minimanc import world")
    for _ in generation.tqdm(range(2), disable=True):
        pass
    assert generation.tqdm.monitor is not None
    assert cap.replaced() == []
    monkeypatch.setattr(generation.tqdm, "monitor_interval", 0)
    assert cap.replaced() == ["minimanc.world.generation.tqdm.monitor_interval"]


@pytest.mark.parametrize("value, message", [
    (type("S", (str,), {"__eq__": lambda s, o: True, "__hash__": str.__hash__})("x"),
     "S, a str subclass; return a plain str"),
    ((1.0, type("F", (float,), {})(2.0)), "F, a float subclass; return a plain float"),
    (np.arange(3).view(type("A", (np.ndarray,), {})), "an ndarray subclass"),
    ([{"k": type("I", (int,), {})(1)}], "an int subclass; return a plain int"),
    (type("Obj", (), {"__eq__": lambda s, o: True})(), "not a plain type"),
])
def test_rigged_answers_are_refused_with_the_expected_type(value, message):
    cap = integrity.Capture("import numpy as np")
    with pytest.raises(integrity.RefusedAnswer) as info:
        integrity.plain_value(value, "f", cap)
    assert message in str(info.value)


@pytest.mark.parametrize("value", [
    1.0, 2, True, None, "s", (1, [2.0, {"a": np.float64(1)}]), np.zeros((2, 3)),
    np.array(["a", "b"]), np.int32(3), np.array([1.0, None], dtype=object)[:1],
])
def test_plain_answers_pass(value):
    integrity.plain_value(value, "f", integrity.Capture("import numpy as np"))


def test_a_function_that_patches_while_called_fails_and_is_restored():
    cap = integrity.capture("import numpy as np")
    original = np.isclose

    def sneaky(x):
        np.isclose = lambda *a, **k: True
        return x

    user = {"sneaky": sneaky}
    with pytest.raises(integrity.TamperedDuringGrading, match="numpy.isclose"):
        integrity.run_grade("assert np.isclose(sneaky(1.0), 2.0)", user, ["sneaky"])
    assert np.isclose is original and cap.replaced() == []


REPLAY = (
    "import re\n"
    "_seen = []\n"
    "def _forge(info):\n"
    "    _seen.append(info.raw_cell)\n"
    "    for token in re.findall(r'minimanc-grade-[0-9a-f]+', info.raw_cell):\n"
    "        print(token + ':[]')   # a forged 'nothing replaced' line\n\n\n"
    "get_ipython().events.register('pre_run_cell', _forge)\n\n\n"
    "def _replay(shell, etype, value, tb, tb_offset=None):\n"
    "    for source in _seen[::-1]:\n"
    "        tokens = re.findall(r'minimanc-grade-[0-9a-f]+', source)\n"
    "        if tokens:\n"
    "            print(tokens[-1])\n"
    "            return\n\n\n"
    "get_ipython().set_custom_exc((BaseException,), _replay)\n\n\n"
    "def max_stable_alpha_semi_implicit(beta, h):\n    return 1.0"
)


def test_a_hook_that_reads_the_grade_cell_and_hides_its_failure_is_removed(tmp_path):
    """A pre_run_cell callback sees the grade cell's text (its token) and forges the
    restore cell's report; a custom exception handler prints the token instead of
    the failure."""
    rows, report = graded(tmp_path, "03_dmp_replay.ipynb", {"ex03_5": REPLAY})
    row = rows["ex03_5_tests"]
    assert row.points == 0, report.format()
    assert "IPython.events.pre_run_cell" in row.message
    assert "IPython.set_custom_exc" in row.message


def test_a_grade_cell_uses_the_captured_imports_not_the_students_globals():
    integrity.capture("import numpy as np")
    fake_np = type("FakeNumpy", (), {"isclose": staticmethod(lambda *a, **k: True)})()
    user = {"abs": lambda x: 0.0, "isinstance": lambda *a: True, "np": fake_np,
            "answer": lambda: 2.0}
    with pytest.raises(AssertionError, match="expected 1"):
        integrity.run_grade("assert np.isclose(answer(), 1.0), 'expected 1'", user, ["answer"])
    with pytest.raises(AssertionError, match="expected 1"):
        integrity.run_grade("assert abs(answer() - 1) < 1e-9, 'expected 1'", user, ["answer"])
    with pytest.raises(AssertionError, match="expected a str"):
        integrity.run_grade("assert isinstance(answer(), str), 'expected a str'", user,
                            ["answer"])
    integrity.run_grade("assert np.isclose(answer(), 2.0)\nseen = 'ran'", user, ["answer"])
    assert user["seen"] == "ran"   # what the cell binds reaches later cells
    assert user["np"] is fake_np and user["abs"](5) == 0.0   # the student's globals stay


def test_a_callable_object_answer_is_wrapped_too():
    integrity.capture("import numpy as np")
    rigged = type("R", (float,), {"__eq__": lambda s, o: True, "__hash__": float.__hash__})
    callable_answer = type("Answer", (), {"__call__": lambda self, x: rigged(x)})()
    with pytest.raises(integrity.RefusedAnswer, match="R, a float subclass"):
        integrity.run_grade("assert f(1.0) == 2.0", {"f": callable_answer}, ["f"])
    integrity.run_grade("assert (f(np.arange(3)) == [0, 2, 4]).all()",
                        {"f": np.vectorize(lambda x: 2 * x)}, ["f"])
    with pytest.raises(integrity.RefusedAnswer, match="x is a .*S, a str subclass"):
        integrity.run_grade("assert x == 'a'", {"x": type("S", (str,), {})("b")}, ["x"])
