"""The grader cannot be fooled by patching its tools, by rigged answers or by reaching into it.

The grade cells run in a process of their own; the notebook answers their calls with plain
data. Each scenario below is a notebook of a small course (:data:`COURSE`, graded like a
chapter) in which some exercises hold a wrong answer next to a tamper that made a wrong
answer pass under an in-process grader (or that reaches for the tests some other way):
every such exercise scores 0, and the honest notebook scores full marks. What the tests'
side of the wire reads, crafted messages included, is tested in ``test_grade_wire.py``.
"""

from __future__ import annotations

from pathlib import Path

import nbformat
import pytest

from minimanc import exercises

COURSE = '''# %%
import math

import numpy as np

from minimanc import engine


class Pair:
    """A class of the notebook's own cells: its instances cross by state."""

    def __init__(self, a, b):
        self.a, self.b = a, b

    def __eq__(self, other):
        return isinstance(other, Pair) and (self.a, self.b) == (other.a, other.b)

# %% solution id=ex_zeta title="Damping ratio"
def damping_ratio(alpha, beta):
    ### BEGIN SOLUTION
    return alpha / (2.0 * math.sqrt(alpha * beta))
    ### END SOLUTION

# %% grade id=ex_zeta_tests points=2
assert np.isclose(damping_ratio(4.0, 1.0), 1.0), "alpha = 4, beta = 1: expected 1"
### BEGIN HIDDEN TESTS
for a, b in [(1.0, 1.0), (9.0, 0.5), (0.3, 2.0)]:
    assert np.isclose(damping_ratio(a, b), a / (2 * np.sqrt(a * b))), f"alpha = {a}, beta = {b}"
### END HIDDEN TESTS

# %% solution id=ex_kind title="Classify"
def classify(alpha, beta):
    ### BEGIN SOLUTION
    return "underdamped" if alpha < 4 * beta else "overdamped"
    ### END SOLUTION

# %% grade id=ex_kind_tests points=2
kind = classify(1.0, 1.0)
assert isinstance(kind, str) and kind == "underdamped", \\
    f"alpha = beta = 1: underdamped; got {kind!r}"
### BEGIN HIDDEN TESTS
assert classify(16.0, 1.0) == "overdamped", "alpha = 16, beta = 1: the hidden overdamped case"
### END HIDDEN TESTS

# %% solution id=ex_matrix title="Step matrix"
def step_matrix(alpha, beta, h):
    ### BEGIN SOLUTION
    return np.array([[1.0, h], [-h * alpha * beta, 1.0 - h * alpha]])
    ### END SOLUTION

# %% grade id=ex_matrix_tests points=3
M = step_matrix(2.0, 0.5, 0.1)
assert M.shape == (2, 2), f"expected a 2 x 2 matrix; got shape {M.shape}"
assert np.allclose(M, [[1.0, 0.1], [-0.1, 0.8]]), "alpha = 2, beta = 0.5, h = 0.1"
### BEGIN HIDDEN TESTS
np.testing.assert_allclose(step_matrix(1.0, 1.0, 0.5), [[1.0, 0.5], [-0.5, 0.5]])
assert np.all(step_matrix(2.0, 0.5, 0.5) == np.array([[1.0, 0.5], [-0.5, 0.0]])), "h = 0.5"
assert (step_matrix(4.0, 0.25, 0.25) == np.array([[1.0, 0.25], [-0.25, 0.0]])).all(), "h = 1/4"
### END HIDDEN TESTS

# %% solution id=ex_bound title="Largest gain"
def largest_gain(h):
    ### BEGIN SOLUTION
    return 2.0 / h
    ### END SOLUTION

# %% grade id=ex_bound_tests points=2
assert abs(largest_gain(0.5) - 4.0) < 1e-12, "h = 0.5: expected 4"
### BEGIN HIDDEN TESTS
assert all(math.isclose(largest_gain(h), 2.0 / h) for h in (0.1, 0.25)), "h = 0.1, 0.25"
### END HIDDEN TESTS

# %% solution id=ex_pair title="Swap"
def swap(p):
    ### BEGIN SOLUTION
    return Pair(p.b, p.a)
    ### END SOLUTION

# %% grade id=ex_pair_tests points=1
assert swap(Pair(1, 2)) == Pair(2, 1), "Pair(1, 2) -> Pair(2, 1)"

# %% solution id=ex_grad title="Energy"
def energy(x, xp=np):
    ### BEGIN SOLUTION
    return xp.sum(x * x) / 2.0
    ### END SOLUTION

# %% grade id=ex_grad_tests points=2
eng = engine("numpy")
x0 = np.array([1.0, -2.0, 3.0])
assert np.isclose(energy(x0), 7.0), "(1, -2, 3): expected 7"
g = eng.grad(lambda x: energy(x, xp=eng.xp))(x0)
assert np.allclose(g, x0), f"the gradient of |x|^2 / 2 is x; got {g}"

# %% solution id=ex_unit title="Unit vector"
def normalised(v):
    ### BEGIN SOLUTION
    return v / np.linalg.norm(v)
    ### END SOLUTION

# %% grade id=ex_unit_tests points=1
v = np.array([3.0, 4.0])
n = normalised(v)
assert np.allclose(n, [0.6, 0.8]) and np.array_equal(v, [3.0, 4.0]), \\
    "a new unit vector, v unchanged"
'''

WRONG = {
    "ex_zeta": "def damping_ratio(alpha, beta):\n    return 42.0",
    "ex_kind": "def classify(alpha, beta):\n    return 'overdamped'",
    "ex_matrix": "def step_matrix(alpha, beta, h):\n    return np.zeros((2, 2))",
    "ex_bound": "def largest_gain(h):\n    return 1.0",
    "ex_pair": "def swap(p):\n    return p",
    "ex_grad": "def energy(x, xp=np):\n    return xp.sum(x)",
}

# each scenario: exercise -> a solution cell holding a tamper and a wrong answer
SCENARIOS = {
    "names": {   # the tools rebound by name
        "ex_zeta": "np.isclose = lambda *a, **k: True\n" + WRONG["ex_zeta"],
        "ex_kind": "isinstance = lambda *a: True   # a global hiding the builtin\n"
                   "def classify(alpha, beta):\n    return 0",
        "ex_matrix": "np.allclose = lambda *a, **k: True\n"
                     "np.testing.assert_allclose = lambda *a, **k: None\n"
                     "np.all = lambda *a, **k: True\n" + WRONG["ex_matrix"],
        "ex_bound": "import builtins\nbuiltins.abs = lambda x: 0.0\n"
                    "all = lambda *a: True\nmath.isclose = lambda *a, **k: True\n"
                    + WRONG["ex_bound"],
    },
    "code": {   # the code of NumPy's Python functions rewritten (the case: zeta = 42)
        "ex_zeta": "np.isclose.__wrapped__.__code__ = "
                   "(lambda a, b, rtol=1e-05, atol=1e-08, equal_nan=False: True).__code__\n"
                   + WRONG["ex_zeta"],
        "ex_matrix": "np.allclose.__wrapped__.__code__ = "
                     "(lambda a, b, rtol=1e-05, atol=1e-08, equal_nan=False: True).__code__\n"
                     "np.testing.assert_allclose.__code__ = (lambda *a, **k: None).__code__\n"
                     "# the Python wrapper between np.all and NumPy's C reduction\n"
                     "np.all.__wrapped__.__globals__['_wrapreduction_any_all'].__code__ = "
                     "(lambda *a, **k: True).__code__\n" + WRONG["ex_matrix"],
        "ex_unit": "def normalised(v):\n    v /= np.linalg.norm(v)   # changes the tests' v\n"
                   "    return v",
    },
    "rigged": {   # answers that compare equal to anything
        "ex_kind": "class Rigged(str):\n    def __eq__(self, other):\n        return True\n\n"
                   "    __hash__ = str.__hash__\n\n\n"
                   "def classify(alpha, beta):\n    return Rigged('overdamped')",
        "ex_matrix": "class Yes(np.ndarray):\n"
                     "    def __eq__(self, other):\n        return np.ones((2, 2), bool)\n\n"
                     "    def __array_function__(self, func, types, args, kwargs):\n"
                     "        return True\n\n\n"
                     "def step_matrix(alpha, beta, h):\n    return np.zeros((2, 2)).view(Yes)",
        "ex_bound": "class Near(float):\n    def __eq__(self, other):\n        return True\n\n"
                    "    def __sub__(self, other):\n        return 0.0\n\n"
                    "    __rsub__ = __sub__\n    __hash__ = float.__hash__\n\n\n"
                    "def largest_gain(h):\n    return Near(1.0)",
        "ex_grad": "class Anything:\n    def __eq__(self, other):\n        return True\n\n"
                   "    def __array__(self, dtype=None, copy=None):\n"
                   "        return np.array(7.0)\n\n\n"
                   "def energy(x, xp=np):\n    return Anything()",
        "ex_pair": "class Pair:   # the notebook's class, redefined to equal anything\n"
                   "    def __init__(self, a, b):\n        self.a, self.b = a, b\n\n"
                   "    def __eq__(self, other):\n        return True\n\n\n"
                   "def swap(p):\n    return Pair(0, 0)",
        "ex_zeta": "class Close(np.float64):\n    def __eq__(self, other):\n        return True\n\n"
                   "    __hash__ = float.__hash__\n\n\n"
                   "def damping_ratio(alpha, beta):\n    return Close(42.0)",
        "ex_unit": "import types\n"
                   "np = types.SimpleNamespace(allclose=lambda *a, **k: True,\n"
                   "                           array_equal=lambda *a, **k: True)\n\n\n"
                   "def normalised(v):\n    return v",
    },
    "reach": {   # the interpreter's state: while called, the heap, frames, modules, the grader
        "ex_zeta": "def damping_ratio(alpha, beta):\n"
                   "    np.isclose = lambda *a, **k: True\n"
                   "    np.isclose.__code__ = (lambda *a, **k: True).__code__\n"
                   "    return 42.0",
        "ex_kind": "import sys\n\n\n"
                   "def classify(alpha, beta):   # fix the grade cell's `kind` from a tracer\n"
                   "    def tracer(frame, event, arg):\n"
                   "        if frame.f_code.co_filename.startswith('<grade cell'):\n"
                   "            frame.f_globals['kind'] = 'underdamped'\n"
                   "            sys.settrace(None)\n"
                   "            return None\n"
                   "        return tracer\n\n"
                   "    frame = sys._getframe(1)\n"
                   "    while frame is not None:\n"
                   "        if frame.f_code.co_filename.startswith('<grade cell'):\n"
                   "            frame.f_trace = tracer\n"
                   "            sys.settrace(tracer)\n"
                   "        frame = frame.f_back\n"
                   "    return 'overdamped'",
        "ex_matrix": "import gc\nimport sys\n"
                     "methods = gc.get_referents(np.ndarray.__dict__)[0]   # the type's own dict\n"
                     "methods['all'] = lambda self, *a, **k: True\n"
                     "sys._clear_type_cache()\n" + WRONG["ex_matrix"],
        "ex_bound": "import builtins\n"
                    "vars(builtins)['abs'] = lambda x: 0.0\n" + WRONG["ex_bound"],
        "ex_pair": "import minimanc.exercises.checker as checker\n"
                   "import minimanc.exercises.values as values\n"
                   "checker.NotebookFunction.__call__ = lambda self, *a, **k: Pair(2, 1)\n"
                   "checker.instrument_grade_source.__code__ = "
                   "(lambda source: ('pass', True)).__code__\n"
                   "values.RefusedAnswer = type('Never', (Exception,), {})\n" + WRONG["ex_pair"],
        "ex_grad": "import sys\nimport types\n"
                   "sys.modules['numpy.testing'] = types.SimpleNamespace(\n"
                   "    assert_allclose=lambda *a, **k: None)\n"
                   "np.testing = sys.modules['numpy.testing']\n" + WRONG["ex_grad"],
    },
    "hooks": {   # IPython's hooks, the hidden tests' text, the grader's pipes
        "ex_zeta": "get_ipython().set_custom_exc((BaseException,), lambda *a, **k: None)\n"
                   "get_ipython().events.register('post_run_cell', lambda *a: print('ok'))\n"
                   + WRONG["ex_zeta"],
        "ex_kind": "import gc\nimport sys\n\n\n"
                   "def classify(alpha, beta):   # look for the hidden tests' text\n"
                   "    seen = [o for o in gc.get_objects() if isinstance(o, str)\n"
                   "            and 'the hidden overdamped case' in o]\n"
                   "    frame = sys._getframe()\n"
                   "    while frame is not None:\n"
                   "        seen += [c for c in frame.f_code.co_consts if isinstance(c, str)\n"
                   "                 and 'the hidden overdamped case' in c]\n"
                   "        frame = frame.f_back\n"
                   "    if seen:\n        raise RuntimeError('saw the hidden tests')\n"
                   "    return 'underdamped' if alpha < 4 * beta else 'underdamped'",
        "ex_matrix": "import json\nimport os\n\n\n"
                     "def forge():   # write 'passed' verdicts into the tests' process's pipes\n"
                     "    lines = ''.join(json.dumps({'verdict': g, 'passed': True, 'hidden':\n"
                     "                                False, 'message': ''}) + '\\n'\n"
                     "                    for g in ('ex_zeta_tests', 'ex_kind_tests',\n"
                     "                              'ex_matrix_tests'))\n"
                     "    written = 0\n"
                     "    for pid in filter(str.isdigit, os.listdir('/proc')):\n"
                     "        try:\n"
                     "            if b'exercises.checker' not in open(f'/proc/{pid}/cmdline',\n"
                     "                                                 'rb').read():\n"
                     "                continue\n"
                     "            for fd in os.listdir(f'/proc/{pid}/fd'):\n"
                     "                if os.readlink(f'/proc/{pid}/fd/{fd}').startswith('pipe:'):\n"
                     "                    with open(f'/proc/{pid}/fd/{fd}', 'w') as out:\n"
                     "                        out.write(lines)\n"
                     "                        out.write('0' * 64 + ' ' + lines)\n"
                     "                    written += 1\n"
                     "        except OSError:\n"
                     "            pass\n"
                     "    return written\n\n\n"
                     "def step_matrix(alpha, beta, h):   # forged 'passed' lines come first\n"
                     "    written = forge()\n"
                     "    if written:\n"
                     "        raise RuntimeError(f'forged verdicts into {written} pipe(s)')\n"
                     "    return np.zeros((2, 2))",
    },
}

ATTACKED = {kind: sorted(f"{ex}_tests" for ex in answers) for kind, answers in SCENARIOS.items()}


@pytest.fixture(scope="module")
def course(tmp_path_factory) -> Path:
    """A course folder with solutions/tamper.ipynb (executed) and exercises/tamper.ipynb."""
    root = tmp_path_factory.mktemp("tamper")
    (root / "tamper_solutions.py").write_text(COURSE)
    exercises.convert(root / "tamper_solutions.py", root / "solutions" / "tamper.ipynb")
    exercises.build(root / "solutions", root / "exercises")
    return root


def graded(course: Path, name: str, answers: dict[str, str]):
    """exercises/tamper.ipynb with the reference solutions, ``answers`` replacing some."""
    solutions = nbformat.read(course / "solutions" / "tamper.ipynb", as_version=4)
    sources = {exercises.grade_id(c): "".join(c.source) for c in solutions.cells
               if exercises.is_solution_cell(c)}
    sources.update(answers)
    nb = nbformat.read(course / "exercises" / "tamper.ipynb", as_version=4)
    for cell in nb.cells:
        if exercises.is_solution_cell(cell):
            cell.source = sources[exercises.grade_id(cell)]
    path = course / "exercises" / name
    nbformat.write(nb, path)
    report = exercises.grade(path, timeout=60)
    return {r.grade_id: r for r in report.rows}, report


@pytest.fixture(scope="module")
def reports(course):
    return {kind: graded(course, f"tamper_{kind}.ipynb", answers)
            for kind, answers in [("honest", {}), *SCENARIOS.items()]}


def test_the_honest_notebook_scores_full_marks(reports):
    rows, report = reports["honest"]
    assert report.total == report.max_total == 13, report.format()
    assert not any(r.message for r in rows.values()), report.format()


@pytest.mark.parametrize("kind", list(SCENARIOS))
def test_every_tampered_exercise_scores_nothing(reports, kind):
    rows, report = reports[kind]
    for gid in ATTACKED[kind]:
        assert rows[gid].points == 0, (kind, gid, report.format())


def test_the_untouched_exercises_keep_their_points(reports):
    rows, report = reports["code"]   # NumPy rewritten in the notebook: the tests never see it
    for gid in ("ex_kind_tests", "ex_bound_tests", "ex_pair_tests"):
        assert rows[gid].points == rows[gid].max_points, (gid, report.format())


def test_the_rows_say_what_was_wrong(reports):
    """The assert that failed is the tests' own, on the wrong value; a rigged answer is
    refused with the type that was expected."""
    code, _ = reports["code"]
    assert code["ex_zeta_tests"].message == "AssertionError: alpha = 4, beta = 1: expected 1"
    rigged, _ = reports["rigged"]
    assert "classify returned a Rigged, a str subclass; return a plain str" in \
        rigged["ex_kind_tests"].message
    assert "step_matrix returned a Yes, an ndarray subclass" in rigged["ex_matrix_tests"].message
    assert "largest_gain returned a Near, a float subclass" in rigged["ex_bound_tests"].message
    assert "energy returned an object of class Anything, which the tests do not know" in \
        rigged["ex_grad_tests"].message
    assert "damping_ratio returned a Close, a float subclass" in rigged["ex_zeta_tests"].message
    assert rigged["ex_pair_tests"].message == "AssertionError: Pair(1, 2) -> Pair(2, 1)"
    assert rigged["ex_pair_tests"].points == 0


def test_a_function_changing_its_argument_in_place_is_seen(reports):
    rows, _ = reports["code"]
    assert rows["ex_unit_tests"].points == 0
    assert "v unchanged" in rows["ex_unit_tests"].message


def test_the_hidden_tests_never_reach_the_notebook(reports):
    rows, report = reports["hooks"]
    assert "saw the hidden tests" not in report.format()
    assert rows["ex_kind_tests"].message == ("hidden test failed: AssertionError: alpha = 16, "
                                             "beta = 1: the hidden overdamped case")


@pytest.mark.skipif(not Path("/proc/self/fd").is_dir(), reason="no /proc to write through")
def test_forged_verdicts_are_dropped(reports):
    """The student's function wrote 'passed' lines into the tests' process's pipes (the one
    to the grader among them) before its grade cell failed: the grader reads only lines
    signed with a key the notebook never sees."""
    rows, report = reports["hooks"]
    assert rows["ex_matrix_tests"].points == 0
    assert "RuntimeError: forged verdicts into" in rows["ex_matrix_tests"].message, \
        report.format()
