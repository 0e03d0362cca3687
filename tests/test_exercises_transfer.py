"""Transfer, not transcription (issue 25): no solution cell copies its tutorial.

A solution cell of ``solutions/NN_*.ipynb`` fails this test when it shares
:data:`MIN_SHARED` or more consecutive statements with one code cell of
``tutorials/NN_*.ipynb`` of the same shape. A statement's shape is its AST
dump after normalisation:

* every identifier a student may rename is replaced by one placeholder:
  variable names, function and class names, parameter names;
* every literal (number, string, ``None``) is replaced by the same placeholder
  as a name, so ``range(1, 61)`` and ``range(1, n)`` have one shape;
* attribute names (``np.zeros``, ``eng.grad``) and keyword names (``xp=``)
  are kept: they are the library calls the cell makes;
* a compound statement (``def``, ``for``, ``if``, ...) is one line, its header;
  its body follows as further lines, in order.

Two statements count as the same line when they are of the same kind
(assignment, ``for``, ``return``, ...) and their shapes agree on at least
:data:`SAME_LINE` of their tokens (``difflib`` ratio): a copy that changes one
literal into a parameter (``0.1`` into ``lr``), or one call in a line
(``eng.value_and_grad`` into ``eng.grad``), is still the same line.

"Consecutive" is read on the solution side. On the tutorial side the matched
statements must come in the same order with at most :data:`MAX_GAP` other
statements between two of them: a transcription that drops the tutorial's
bookkeeping lines (a list of losses for a plot, a ``print``) is still a
transcription.

A transcription may also *reorder* the tutorial (move a definition up, swap two
independent lines), which breaks every run. So a solution cell also fails when
at least :data:`MIN_REORDERED` of its statements, and at least
:data:`REORDERED_SHARE` of them, are matched one to one (in any order) by
statements of one stretch of a tutorial cell at most :data:`WINDOW` times the
solution's length: the matched lines must come from one place, so generic lines
scattered over a long cell (``np.zeros``, ``for``, ``return``) do not add up.

No exercise of any chapter transcribes its tutorial (the last one, 8.5, now asks for
the step of the eq.-7 variants the tutorial does not show), so the repository test
allows none.

The same measure keeps the answers out of the grade cells (issue 40): the *visible*
part of a grade cell (its hidden tests removed, as ``minimanc exercises build``
shows it) fails when it shares :data:`MIN_SHARED` consecutive statements with the
solution region of any exercise of its notebook, or is a reordered copy of one, or
holds one of a solution region's formulas verbatim: an arithmetic expression of at
least two operations and :data:`MIN_FORMULA` characters (``np.eye(2) + hA + 0.5 * hA
@ hA``, the answer to 3.6 once printed in 3.7's grade cell), compared after
``ast.unparse`` so that spacing and parentheses do not hide it.
"""

from __future__ import annotations

import ast
import copy
import difflib
import functools
import re
import textwrap
from pathlib import Path

import nbformat

from minimanc import exercises

ROOT = Path(__file__).resolve().parent.parent
MIN_SHARED = 6
MAX_GAP = 3
SAME_LINE = 0.8
MIN_REORDERED = 9
REORDERED_SHARE = 2 / 3
WINDOW = 2
MIN_FORMULA = 15
_TOKEN = re.compile(r"\w+|[^\w\s]")
_BODIES = ("body", "orelse", "finalbody", "handlers")

#: Exercises that still share >= MIN_SHARED statements with their tutorial
#: (issue 25: to be rewritten as transfer tasks chapter by chapter). Each entry
#: names the exercise and the tutorial cell it follows.
class _Normalise(ast.NodeTransformer):
    """Rename identifiers and literals to one placeholder, keep attribute names."""

    def visit_Name(self, node: ast.Name) -> ast.AST:
        return ast.Name(id="_", ctx=ast.Load())

    def visit_Constant(self, node: ast.Constant) -> ast.AST:
        return ast.Name(id="_", ctx=ast.Load())

    def visit_arg(self, node: ast.arg) -> ast.AST:
        return ast.arg(arg="_")

    def _named(self, node: ast.AST) -> ast.AST:
        node.name = "_"
        node.decorator_list = []
        node.returns = None
        return self.generic_visit(node)

    visit_FunctionDef = visit_AsyncFunctionDef = visit_ClassDef = _named


def statement_shapes(source: str) -> list[tuple[str, ...]]:
    """The normalised shapes of the statements of ``source``, in reading order."""
    lines = [ln for ln in source.splitlines() if not ln.lstrip().startswith(("%", "!"))]
    shapes: list[tuple[str, ...]] = []

    def walk(statements: list[ast.stmt]) -> None:
        for statement in statements:
            header = copy.deepcopy(statement)
            for field in _BODIES:
                if hasattr(header, field):
                    setattr(header, field, [])
            header = _Normalise().visit(header)
            dump = ast.dump(header, annotate_fields=False, include_attributes=False)
            shapes.append(tuple(_TOKEN.findall(dump)))
            for field in _BODIES:
                for child in getattr(statement, field, []) or []:
                    walk(child.body if isinstance(child, ast.excepthandler) else [child])

    walk(ast.parse("\n".join(lines)).body)
    return shapes


@functools.cache
def same_line(a: tuple[str, ...], b: tuple[str, ...]) -> bool:
    """Whether two statements are of one kind and their shapes agree on at least
    ``SAME_LINE`` of their tokens."""
    if a == b:
        return True
    if a[:1] != b[:1]:
        return False
    matcher = difflib.SequenceMatcher(None, a, b, autojunk=False)
    return (matcher.real_quick_ratio() >= SAME_LINE and matcher.quick_ratio() >= SAME_LINE
            and matcher.ratio() >= SAME_LINE)


def longest_shared_run(solution: list[tuple[str, ...]], tutorial: list[tuple[str, ...]],
                       max_gap: int = MAX_GAP) -> int:
    """Longest run of consecutive ``solution`` statements found in order in ``tutorial``
    with at most ``max_gap`` tutorial statements between two matched ones."""
    best = 0
    previous = [0] * len(tutorial)  # run length ending at solution[i - 1] matched at tutorial[j]
    for shape in solution:
        current = [0] * len(tutorial)
        for j, other in enumerate(tutorial):
            if same_line(shape, other):
                window = previous[max(0, j - max_gap - 1):j]
                current[j] = 1 + max(window, default=0)
                best = max(best, current[j])
        previous = current
    return best


def reordered_shared(solution: list[tuple[str, ...]], tutorial: list[tuple[str, ...]],
                     window: float = WINDOW) -> int:
    """Most ``solution`` statements matched one to one, in any order, by the statements
    of one stretch of ``tutorial`` of ``window`` times the solution's length."""
    if not solution or not tutorial:
        return 0
    same = [[same_line(a, b) for b in tutorial] for a in solution]
    length = max(1, int(window * len(solution)))
    best = 0
    for start in range(max(1, len(tutorial) - length + 1)):
        used: set[int] = set()
        for row in same:
            j = next((j for j in range(start, min(len(tutorial), start + length))
                      if row[j] and j not in used), None)
            if j is not None:
                used.add(j)
        best = max(best, len(used))
    return best


def is_reordered_copy(solution: list[tuple[str, ...]], tutorial: list[tuple[str, ...]]) -> bool:
    """Whether ``solution`` is a reordered copy of a stretch of ``tutorial``."""
    shared = reordered_shared(solution, tutorial)
    return shared >= MIN_REORDERED and shared >= REORDERED_SHARE * len(solution)


def transcriptions(solutions: Path, tutorials: Path) -> dict[str, str]:
    """Map each exercise id whose solution cell shares >= MIN_SHARED statements with a
    tutorial cell to a description ``"<tutorial> cell <k>: <n> statements"``."""
    found: dict[str, str] = {}
    for path in sorted(solutions.glob("*.ipynb")):
        tutorial = tutorials / path.name
        if not tutorial.exists():
            continue
        tut_cells = [(k, statement_shapes(c.source))
                     for k, c in enumerate(nbformat.read(tutorial, as_version=4).cells)
                     if c.cell_type == "code"]
        for cell in nbformat.read(path, as_version=4).cells:
            if not exercises.is_solution_cell(cell) or cell.cell_type != "code":
                continue
            shapes = statement_shapes(cell.source)
            for k, tut in tut_cells:
                run = longest_shared_run(shapes, tut)
                if run >= MIN_SHARED:
                    found[exercises.grade_id(cell)] = f"{tutorial.name} cell {k}: {run} statements"
                    break
                if is_reordered_copy(shapes, tut):
                    found[exercises.grade_id(cell)] = (
                        f"{tutorial.name} cell {k}: {reordered_shared(shapes, tut)} of "
                        f"{len(shapes)} statements, reordered")
                    break
    return found


# ------------------------------------------------------------------- the detector
TUTORIAL = """
eng = engine("numpy")
xp = eng.xp
N = 10
def loss(z):
    a, b = dmp.gains_from_logits(z[0], z[1], xp=xp)
    return xp.mean((a - b) ** 2)
z = np.zeros(2)
losses = []
for it in range(1, 61):
    g = eng.grad(loss)(z)
    losses.append(float(loss(z)))
    z = z - 0.1 * g
"""


def test_a_renamed_copy_is_a_transcription():
    copied = """
def fit(target, lr):
    engine_ = engine("numpy")
    array_api = engine_.xp
    def objective(logits):
        p, q = dmp.gains_from_logits(logits[0], logits[1], xp=array_api)
        return array_api.mean((p - q) ** 2)
    w = np.zeros(2)
    for k in range(1, lr):
        grad = engine_.grad(objective)(w)
        w = w - lr * grad
    return w
"""
    run = longest_shared_run(statement_shapes(copied), statement_shapes(TUTORIAL))
    assert run >= MIN_SHARED, run


def test_one_changed_call_or_literal_keeps_the_line():
    changed = TUTORIAL.replace("eng.grad", "eng.value_and_grad").replace("0.1 * g", "lr * g")
    run = longest_shared_run(statement_shapes(changed), statement_shapes(TUTORIAL))
    assert run == len(statement_shapes(TUTORIAL)), run


def test_five_shared_statements_or_other_code_are_not():
    five = """
eng = engine("numpy")
xp = eng.xp
def loss(z):
    a, b = dmp.gains_from_logits(z[0], z[1], xp=xp)
    return xp.mean((a - b) ** 2)
"""
    assert longest_shared_run(statement_shapes(five), statement_shapes(TUTORIAL)) == 5
    other = """
def bound(beta, h):
    lo, hi = 0.0, 1.0 / h
    while rho(hi, beta, h) < 1:
        lo, hi = hi, 2.0 * hi
    for _ in range(100):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if rho(mid, beta, h) < 1 else (lo, mid)
    return float(lo)
"""
    assert longest_shared_run(statement_shapes(other), statement_shapes(TUTORIAL)) < 3


def test_gaps_on_the_tutorial_side_are_bounded():
    spread = "\n".join(f"{line}\nprint(1)\nprint(2)\nprint(3)\nprint(4)"
                       for line in ("a = f(x)", "b = g(a)", "c = h(b)"))
    copy_ = "a = f(x)\nb = g(a)\nc = h(b)"
    assert longest_shared_run(statement_shapes(copy_), statement_shapes(spread)) == 1
    assert longest_shared_run(statement_shapes(copy_), statement_shapes(spread), max_gap=4) == 3


#: Exercise 3.6 as it stood before issue 25: tutorial 03's training cell, transcribed.
OLD_EXERCISE_3_6 = """
def fit_gains(target, goal, steps, iters=60, lr=0.1):
    eng = engine("numpy")
    xp = eng.xp

    def loss(z):
        a, b = dmp.gains_from_logits(z[0], z[1], xp=xp)
        pred = dmp.rollout(xp.zeros(1), xp.zeros(1), goal, a, b, dmp.DT, steps, xp=xp).dy[1:]
        return xp.mean((pred - target) ** 2)

    z, m, v = np.zeros(2), np.zeros(2), np.zeros(2)
    for k in range(1, iters + 1):
        g = np.asarray(eng.grad(loss)(z))
        m = 0.9 * m + 0.1 * g
        v = 0.999 * v + 0.001 * g**2
        z = z - lr * (m / (1 - 0.9**k)) / (np.sqrt(v / (1 - 0.999**k)) + 1e-12)
    a, b = dmp.gains_from_logits(z[0], z[1])
    return float(a), float(b)
"""


def test_the_old_exercise_3_6_is_flagged():
    cells = nbformat.read(ROOT / "tutorials" / "03_dmp.ipynb", as_version=4).cells
    training = [c.source for c in cells
                if c.cell_type == "code" and "Adam, written out" in c.source]
    assert len(training) == 1, "tutorial 03's training cell not found"
    run = longest_shared_run(statement_shapes(OLD_EXERCISE_3_6), statement_shapes(training[0]))
    assert run >= MIN_SHARED, run


#: Exercise 5.6 as it stood before issue 25: tutorial 05's training cell, reordered
#: (``eng = engine(...)`` above ``def loss``, the loss with one argument instead of five).
OLD_EXERCISE_5_6 = """
from minimanc import engine


def fit_W(ps, targets, W0, steps=300, lr=20.0):
    eng = engine("numpy")

    def loss(W):
        qs = vagn.rollout(targets[0], ps, W, xp=eng.xp)
        return eng.xp.mean(eng.xp.sum((qs[1:] - targets[1:]) ** 2, axis=-1))

    value_and_grad = eng.value_and_grad(loss)
    W, losses = np.array(W0, dtype=float), []
    for _ in range(steps):
        L, g = value_and_grad(W)
        W = W - lr * np.asarray(g)
        losses.append(float(L))
    return W, losses
"""


def test_the_old_exercise_5_6_is_flagged_as_a_reordered_copy():
    cells = nbformat.read(ROOT / "tutorials" / "05_vagn.ipynb", as_version=4).cells
    training = [c.source for c in cells
                if c.cell_type == "code" and "eng.value_and_grad(loss)" in c.source]
    assert len(training) == 1, "tutorial 05's training cell not found"
    old, tut = statement_shapes(OLD_EXERCISE_5_6), statement_shapes(training[0])
    assert longest_shared_run(old, tut) < MIN_SHARED     # the run rule alone misses it
    assert is_reordered_copy(old, tut), reordered_shared(old, tut)


def test_a_shuffled_copy_is_caught_and_scattered_generic_lines_are_not():
    lines = ["a = np.zeros((3, 4))", "b, c = a.shape", "d = a.sum(axis=0) / b",
             "e = [x ** 2 for x in d]", "f = dict(zip(e, d))", "g = sorted(f, key=abs)",
             "h = np.linalg.norm(a, ord=2)", "k = {i: j for i, j in f.items()}",
             "m = a.T @ a + h * np.eye(4)", "n = max(g, default=None) if g else 0"]
    shuffled = "\n".join(lines[5:] + lines[:5])
    assert longest_shared_run(statement_shapes(shuffled), statement_shapes("\n".join(lines))) == 5
    assert is_reordered_copy(statement_shapes(shuffled), statement_shapes("\n".join(lines)))
    scattered = "\n".join(f"{line}\n" + "\n".join(f"print({j})" for j in range(30))
                          for line in lines)
    assert not is_reordered_copy(statement_shapes(shuffled), statement_shapes(scattered))


# ------------------------------------------------------------------- the repository
def test_no_solution_cell_transcribes_its_tutorial():
    found = transcriptions(ROOT / "solutions", ROOT / "tutorials")
    assert not found, f"solution cells that transcribe their tutorial: {found}"


# ------------------------------------------------------- answers in the grade cells
def solution_regions(source: str) -> list[str]:
    """The code between the solution markers of a cell, each region dedented."""
    regions: list[str] = []
    region: list[str] | None = None
    for line in source.split("\n"):
        if line.strip() == exercises.BEGIN_SOLUTION:
            region = []
        elif line.strip() == exercises.END_SOLUTION:
            regions.append(textwrap.dedent("\n".join(region or [])))
            region = None
        elif region is not None:
            region.append(line)
    return regions


def formulas(source: str) -> set[str]:
    """The arithmetic expressions of ``source`` with at least two binary operations and
    ``MIN_FORMULA`` characters, as ``ast.unparse`` writes them."""
    found = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.BinOp) and sum(isinstance(n, ast.BinOp)
                                               for n in ast.walk(node)) >= 2:
            text = ast.unparse(node)
            if len(text) >= MIN_FORMULA:
                found.add(text)
    return found


def code_parts(source: str) -> tuple[list[tuple[str, ...]], set[str]]:
    """The statement shapes and the formulas of ``source``."""
    return statement_shapes(source), formulas(source)


def leak_of(visible: tuple[list, set], solution: tuple[list, set]) -> str | None:
    """Why visible grade-cell code gives away a solution region, both as
    :func:`code_parts`: a run of statements, a reordered copy, a formula; or None."""
    (shown, shown_formulas), (shapes, answer_formulas) = visible, solution
    run = longest_shared_run(shapes, shown)
    if run >= MIN_SHARED:
        return f"{run} statements in a row"
    if len(shapes) >= MIN_REORDERED and is_reordered_copy(shapes, shown):
        return f"{reordered_shared(shapes, shown)} of {len(shapes)} statements, reordered"
    common = answer_formulas & shown_formulas
    return f"the formula {sorted(common)[0]!r}" if common else None


def answer_leaks(visible: str, solution: str) -> str | None:
    """:func:`leak_of` for the visible code ``visible`` and the solution region ``solution``."""
    return leak_of(code_parts(visible), code_parts(solution))


def grade_cell_leaks(solutions: Path) -> dict[str, str]:
    """Map ``"<notebook> <grade id>"`` to the exercise whose solution its visible part
    gives away, and how."""
    found: dict[str, str] = {}
    for path in sorted(solutions.glob("*.ipynb")):
        cells = nbformat.read(path, as_version=4).cells
        answers = {exercises.grade_id(c): code_parts("\n\n".join(solution_regions(c.source)))
                   for c in cells if exercises.is_solution_cell(c) and c.cell_type == "code"}
        for cell in cells:
            if not exercises.is_grade_cell(cell) or cell.cell_type != "code":
                continue
            visible = code_parts(exercises.strip_hidden(cell.source, f"{path.name}"))
            for exercise, answer in answers.items():
                why = leak_of(visible, answer)
                if why:
                    found[f"{path.name} {exercises.grade_id(cell)}"] = f"{exercise}: {why}"
                    break
    return found


#: Exercise 3.7's grade cell before issue 40: its own step matrices, RK2's the answer to 3.6.
OLD_GRADE_3_7 = """
def step_matrix7(a, b, h, method):
    hA = h * np.array([[0.0, 1.0], [-a * b, -a]])
    if method == "euler":
        return np.eye(2) + hA
    if method == "rk2":
        return np.eye(2) + hA + 0.5 * hA @ hA
    return np.array([[1.0 - h * h * a * b, h * (1.0 - h * a)], [-h * a * b, 1.0 - h * a]])
### BEGIN HIDDEN TESTS
assert step_matrix7(1.0, 1.0, 0.5, "rk2").shape == (2, 2)
### END HIDDEN TESTS
"""
SOLUTION_3_6 = """
hA = h * np.array([[0.0, 1.0], [-alpha * beta, -alpha]])
return np.eye(2)+hA + (0.5*hA)@hA
"""


def test_a_formula_of_another_exercise_in_a_grade_cell_is_a_leak():
    visible = exercises.strip_hidden(OLD_GRADE_3_7, "old 3.7")
    why = answer_leaks(visible, SOLUTION_3_6.replace("return ", "M = "))
    assert why == "the formula 'np.eye(2) + hA + 0.5 * hA @ hA'", why


def test_hidden_tests_values_and_short_expressions_are_not_leaks():
    hidden_only = "x = f(1.0)\n### BEGIN HIDDEN TESTS\nM = np.eye(2) + hA + 0.5 * hA @ hA\n" \
                  "### END HIDDEN TESTS"
    visible = exercises.strip_hidden(hidden_only, "hidden")
    assert answer_leaks(visible, "M = np.eye(2) + hA + 0.5 * hA @ hA") is None
    assert answer_leaks("assert np.isclose(got, 4.5714), got", "return 4.0 / (h * (2.0 - h * b))") \
        is None
    assert answer_leaks("mid = lo + hi", "mid = lo + hi") is None   # one operation: no formula


def test_a_copied_function_in_a_grade_cell_is_a_leak():
    copied = TUTORIAL.replace("eng.grad", "eng.value_and_grad")
    run = len(statement_shapes(TUTORIAL))
    assert answer_leaks(copied, TUTORIAL) == f"{run} statements in a row"


#: Grade cells of chapters outside this branch that still show a solution's formula;
#: their owners remove them (the test fails until the list is exactly what is found).
KNOWN_LEAKS: dict[str, str] = {}


def test_no_visible_grade_cell_shows_a_solution_of_its_notebook():
    found = grade_cell_leaks(ROOT / "solutions")
    new = {k: v for k, v in found.items() if KNOWN_LEAKS.get(k) != v.split(":")[0]}
    assert not new, f"visible grade cells that give a solution away: {new}"
    fixed = sorted(set(KNOWN_LEAKS) - set(found))
    assert not fixed, f"no longer leaking, remove from KNOWN_LEAKS: {fixed}"
