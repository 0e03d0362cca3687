# %% [markdown]
# # Chapter 1 — Exercises: build reverse-mode autodiff
#
# Modules built in this chapter: `minimanc.autodiff` (`core.py`, `numpy.py`,
# `check.py`) and `minimanc.engine`. Read `tutorials/01_autodiff.ipynb` first.
#
# You will write the pieces of a reverse-mode engine yourself: summing a
# cotangent back over broadcasting, the vector-Jacobian products (VJPs) of
# `multiply`, `exp`, `sum` and `matmul`, the topological sort of the tape,
# `grad` itself for a small scalar engine, and finally the computation graph
# with the cotangent that flows along each of its edges. Then two things the
# tutorial does not show: the VJPs of a linear solve (1.7, derived by you) and an
# experiment on the step of a finite difference (1.8) with a written answer,
# graded by hand. The last cell draws the chapter's graph figure from *your*
# `edge_cotangents`. Every grade cell checks your code against central
# differences or the library. Replace each
# `raise NotImplementedError(...)` with your code and run the grade cell below
# it; `minimanc grade exercises/01_autodiff.ipynb` scores the whole notebook.

# %%
import math

import matplotlib.pyplot as plt
import numpy as np

import minimanc.autodiff.numpy as anp
from minimanc.autodiff import (
    check_grads,
    computation_graph,
    defvjp,
    grad,
    primitive,
    toposort,
    unbroadcast,
)
from minimanc.viz.exercises import plot_edge_cotangents

rng = np.random.default_rng(0)

# %% [markdown]
# ## Exercise 1.1 — sum a cotangent back over broadcasting
# When `x` of shape `shape` is broadcast to the shape of `g` (new leading axes,
# and axes of size one stretched), every element of `x` is copied several
# times. The VJP of a copy is a sum: return `g` summed back to `shape`.
# Example: `shape=(3, 1)`, `g.shape == (2, 3, 4)` → sum over axis 0 (new) and
# axis 2 (stretched, keeping it with size one).

# %% solution id=ex01_1 title="Unbroadcast a cotangent" forbids="minimanc.autodiff.core.unbroadcast"  # noqa: E501
def my_unbroadcast(shape, g):
    ### BEGIN SOLUTION
    g = np.asarray(g)
    extra = g.ndim - len(shape)
    if extra > 0:
        g = g.sum(axis=tuple(range(extra)))
    stretched = tuple(i for i, n in enumerate(shape) if n == 1 and g.shape[i] != 1)
    if stretched:
        g = g.sum(axis=stretched, keepdims=True)
    return g
    ### END SOLUTION

# %% grade id=ex01_1_tests points=2
g = np.arange(24.0).reshape(2, 3, 4)
out = my_unbroadcast((3, 1), g)
assert out.shape == (3, 1), f"shape (3, 1) expected, got {out.shape}"
assert np.allclose(out, g.sum(axis=(0, 2))[:, None]), "(3, 1): sum over axis 0 (new) and 2"
assert np.allclose(my_unbroadcast((4,), g), g.sum(axis=(0, 1))), "(4,): sum over axes 0, 1"
assert np.allclose(my_unbroadcast((2, 3, 4), g), g), "same shape: g unchanged"
### BEGIN HIDDEN TESTS
got0 = my_unbroadcast((), g)
assert np.shape(got0) == () and np.isclose(got0, g.sum()), \
    f"shape (): expected the sum of all of g, {g.sum():g}, got {got0!r}"
# the sums written out by hand: new leading axes go, stretched axes of size one stay
expected = {(1, 1, 4): g.sum(axis=(0, 1), keepdims=True),
            (2, 1, 1): g.sum(axis=(1, 2), keepdims=True),
            (1,): np.array([g.sum()]),
            (1, 3, 1): g.sum(axis=(0, 2), keepdims=True)}
for shape, want in expected.items():
    got = my_unbroadcast(shape, g)
    assert np.shape(got) == shape, f"shape {shape}: expected shape {shape}, got {np.shape(got)}"
    assert np.allclose(got, want), \
        f"shape {shape}: expected {want.ravel().tolist()}, got {np.ravel(got).tolist()}"
got13 = my_unbroadcast((1, 3, 1), g)[0, :, 0]
want13 = [float(g[:, i].sum()) for i in range(3)]
assert np.allclose(got13, want13), f"shape (1, 3, 1): expected {want13}, got {got13.tolist()}"
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 1.2 — VJPs of `multiply`, `exp` and `sum`
# A VJP receives the output cotangent `g`, the forward result `ans` and the
# forward arguments, and returns the cotangent of one argument, **with that
# argument's shape**. Write:
#
# * `multiply_vjp_x(g, ans, x, y)`: cotangent of `x` in `x * y` (both may be
#   broadcast — use `unbroadcast(x, ...)` from the library);
# * `exp_vjp(g, ans, x)`: cotangent of `x` in `exp(x)` (reuse `ans`);
# * `sum_vjp(g, ans, x, axis=None, keepdims=False)`: cotangent of `x` in
#   `np.sum(x, axis, keepdims)` — every element of `x` receives the cotangent of
#   the sum it went into (`np.expand_dims` and `np.broadcast_to` help).
#
# The grade cell registers them on fresh primitives with `defvjp` and checks
# the gradients with `check_grads`.

# %% solution id=ex01_2 title="VJPs of multiply, exp and sum"
def multiply_vjp_x(g, ans, x, y):
    ### BEGIN SOLUTION
    return unbroadcast(x, g * y)
    ### END SOLUTION


def exp_vjp(g, ans, x):
    ### BEGIN SOLUTION
    return g * ans
    ### END SOLUTION


def sum_vjp(g, ans, x, axis=None, keepdims=False):
    ### BEGIN SOLUTION
    if axis is not None and not keepdims:
        g = np.expand_dims(g, axis)
    return np.broadcast_to(g, np.shape(x))
    ### END SOLUTION

# %% grade id=ex01_2_tests points=3
my_multiply = primitive(np.multiply)
defvjp(my_multiply, multiply_vjp_x, lambda g, ans, x, y: multiply_vjp_x(g, ans, y, x))
my_exp = primitive(np.exp)
defvjp(my_exp, exp_vjp)


@primitive
def my_sum(x, axis=None, keepdims=False):
    return np.sum(x, axis=axis, keepdims=keepdims)


defvjp(my_sum, sum_vjp)

a, b = rng.normal(size=(3, 1)), rng.normal(size=(4,))
assert np.allclose(multiply_vjp_x(np.ones((3, 4)), None, a, b), b.sum() * np.ones((3, 1))), \
    "x of shape (3, 1) times y (4,): each x_i receives sum_j g_ij y_j"
check_grads(lambda a, b: my_sum(my_exp(my_multiply(a, b)) * a), a, b, verbose=False)
check_grads(lambda x: anp.sum(my_sum(my_exp(x), axis=1) ** 2), rng.normal(size=(2, 3)),
            verbose=False)
### BEGIN HIDDEN TESTS
test_rng = np.random.default_rng(120)  # the tests' own draws, not the notebook's rng
cases2 = [("sum(x * x, axis=(0, 2), keepdims=True), x (2, 3, 2)",
           lambda x: anp.sum(my_sum(x * x, axis=(0, 2), keepdims=True) ** 2),
           (test_rng.normal(size=(2, 3, 2)),)),
          ("sum(x, axis=-1), x (2, 3)", lambda x: anp.sum(my_sum(x, axis=-1) * np.arange(2.0)),
           (test_rng.normal(size=(2, 3)),)),
          ("sum((a b)^2), a (2, 1, 3), b (4, 1)", lambda a, b: my_sum(my_multiply(a, b) ** 2),
           (test_rng.normal(size=(2, 1, 3)), test_rng.normal(size=(4, 1))))]
for case2, f2, args2 in cases2:
    try:
        check_grads(f2, *args2, verbose=False)
    except AssertionError as exc:
        raise AssertionError(f"{case2}: expected the central differences, got: "
                             f"{' '.join(str(exc).split())[:160]}") from None
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 1.3 — VJP of a matrix product
# For $Y = AB$ with $A \in \mathbb{R}^{n\times k}$, $B \in \mathbb{R}^{k\times m}$ and
# cotangent $\bar Y$, derive $\bar A$ and $\bar B$ from
# $Y_{ij} = \sum_l A_{il} B_{lj}$. Return both as a tuple. Never build the
# Jacobian.
#
# <details><summary>Hint 1 (the idea)</summary>
#
# One entry $A_{il}$ enters every $Y_{ij}$ of row $i$: its cotangent is a sum over
# $j$ of $\bar Y_{ij}$ times the local derivative $\partial Y_{ij}/\partial A_{il}$.
# </details>
#
# <details><summary>Hint 2 (the method)</summary>
#
# A sum over a shared index of two arrays is a matrix product. Write the sum of
# Hint 1 out, then find the product of $\bar Y$ and $B$ (transposed or not) whose
# shape is $A$'s; do the same for $\bar B$.
# </details>

# %% solution id=ex01_3 title="VJP of matmul" forbids="minimanc.autodiff.numpy._matmul_vjp_x,minimanc.autodiff.numpy._matmul_vjp_y"  # noqa: E501
def matmul_vjps(g, A, B):
    ### BEGIN SOLUTION
    return g @ B.T, A.T @ g
    ### END SOLUTION

# %% grade id=ex01_3_tests points=2
my_matmul = primitive(np.matmul)
defvjp(my_matmul, lambda g, ans, A, B: matmul_vjps(g, A, B)[0],
       lambda g, ans, A, B: matmul_vjps(g, A, B)[1])
A, B = rng.normal(size=(3, 4)), rng.normal(size=(4, 2))
gA, gB = matmul_vjps(np.ones((3, 2)), A, B)
assert gA.shape == A.shape and gB.shape == B.shape, "dA has the shape of A, dB of B"
check_grads(lambda A, B: anp.sum(anp.tanh(my_matmul(A, B))), A, B, verbose=False)
### BEGIN HIDDEN TESTS
W = rng.normal(size=(3, 2))
# d/dA sum((A B) * W) = W B^T and d/dB = A^T W, written element by element
ref_A = np.array([[sum(W[i, j] * B[l, j] for j in range(2)) for l in range(4)] for i in range(3)])
ref_B = np.array([[sum(A[i, l] * W[i, j] for i in range(3)) for j in range(2)] for l in range(4)])
mine = grad(lambda A, B: anp.sum(my_matmul(A, B) * W), argnums=(0, 1))(A, B)
for name3, want3, got3 in (("A", ref_A, mine[0]), ("B", ref_B, mine[1])):
    assert np.shape(got3) == want3.shape and np.allclose(got3, want3), \
        (f"grad of sum((A B) * W) for A (3, 4), B (4, 2), the cotangent of {name3}: expected "
         f"{np.round(want3, 4).tolist()}, got {np.round(np.asarray(got3), 4).tolist()}")
gA, gB = matmul_vjps(W, A, B)
assert np.allclose(gA, ref_A) and np.allclose(gB, ref_B), \
    (f"matmul_vjps(W, A, B), W (3, 2): expected a max error 0, got "
     f"{max(np.abs(gA - ref_A).max(), np.abs(gB - ref_B).max()):.3g}")
### END HIDDEN TESTS

# %% [markdown]
# ## A scalar engine for the last two exercises
# To see the whole backward pass at once, here is a complete tape for
# scalars: a `Var` holds a value, its `parents` (a tuple) and the **local
# derivatives** $\partial\,\text{self} / \partial\,\text{parent}$ (a tuple of
# floats). With scalars, a VJP is just `g * local_derivative`.

# %%
class Var:
    """A scalar on the tape."""

    def __init__(self, value, parents=(), local_grads=()):
        self.value = float(value)
        self.parents = parents
        self.local_grads = local_grads

    def __add__(self, other):
        other = as_var(other)
        return Var(self.value + other.value, (self, other), (1.0, 1.0))

    def __mul__(self, other):
        other = as_var(other)
        return Var(self.value * other.value, (self, other), (other.value, self.value))

    def __sub__(self, other):
        return self + (-1.0) * as_var(other)

    __radd__ = __add__
    __rmul__ = __mul__

    def __repr__(self):
        return f"Var({self.value:.4f})"


def as_var(v):
    return v if isinstance(v, Var) else Var(v)


def vsin(v):
    return Var(math.sin(v.value), (v,), (math.cos(v.value),))


def vexp(v):
    e = math.exp(v.value)
    return Var(e, (v,), (e,))


z = vsin(Var(0.5) * 3.0) + 1.0
print(z, "parents:", z.parents)

# %% [markdown]
# ## Exercise 1.4 — topological sort, iteratively
# Return the list of all `Var`s reachable from `end`, **each before its
# parents** (so `end` comes first), each exactly once. Do not recurse: use an
# explicit stack, so that a chain of 10,000 operations works. Keep track of
# visited nodes by `id(node)` (a `Var` is not hashable by value), and visit
# parents in their tuple order so the result is deterministic.

# %% solution id=ex01_4 title="Topological sort" forbids="minimanc.autodiff.core.toposort"  # noqa: E501
def topo_order(end):
    ### BEGIN SOLUTION
    order, seen = [], set()
    stack = [(end, False)]
    while stack:
        node, parents_done = stack.pop()
        if parents_done:
            order.append(node)
            continue
        if id(node) in seen:
            continue
        seen.add(id(node))
        stack.append((node, True))
        for p in reversed(node.parents):
            if id(p) not in seen:
                stack.append((p, False))
    return order[::-1]
    ### END SOLUTION

# %% grade id=ex01_4_tests points=2
def check_order(order, end):
    position = {id(n): i for i, n in enumerate(order)}
    assert order[0] is end and len(position) == len(order), "end first, no duplicates"
    for n in order:
        for p in n.parents:
            assert position[id(p)] > position[id(n)], "every node comes before its parents"


x = Var(0.3)
y = vsin(x * x) + x * vexp(x)
order = topo_order(y)
check_order(order, y)
assert sum(n is x for n in order) == 1 and len(order) == 6, \
    f"6 nodes, x once, expected; got {len(order)} nodes"
### BEGIN HIDDEN TESTS
deep = x
for _ in range(10_000):
    deep = deep * 1.0001 + 0.0
deep_order = topo_order(deep)
check_order(deep_order, deep)
assert len(deep_order) == 1 + 4 * 10_000, \
    f"a chain of 10,000 steps: expected 40,001 nodes, got {len(deep_order)}"
assert deep_order[-1] is x, \
    f"a chain of 10,000 steps: expected the input last, got {deep_order[-1]}"
again = topo_order(y)
assert [id(n) for n in again] == [id(n) for n in order], \
    f"the same graph twice: expected the same order, got {order} then {again}"
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 1.5 — `grad` itself
# Write `var_grad(f)`: it returns a function that takes floats `xs`, wraps
# them in `Var`s, runs `f`, and returns the tuple of derivatives
# $\partial f / \partial x_i$. Seed the output's cotangent with 1, walk the
# nodes in topological order (use the library's
# `toposort(end, parents_of=lambda v: v.parents)`, so this exercise does not
# depend on the previous one), and **add** `g * local_grad` into each parent's
# cotangent. An input that does not influence the output has derivative 0.

# %% solution id=ex01_5 title="grad from scratch"
def var_grad(f):
    def df(*xs):
        ### BEGIN SOLUTION
        inputs = [Var(x) for x in xs]
        out = f(*inputs)
        cot = {id(out): 1.0}
        for node in toposort(out, parents_of=lambda v: v.parents):
            g = cot.get(id(node), 0.0)
            for parent, local in zip(node.parents, node.local_grads):
                cot[id(parent)] = cot.get(id(parent), 0.0) + g * local
        return tuple(cot.get(id(v), 0.0) for v in inputs)
        ### END SOLUTION

    return df

# %% grade id=ex01_5_tests points=3
def central(f, xs, eps=1e-6):
    out = []
    for i in range(len(xs)):
        hi = [v + (eps if j == i else 0.0) for j, v in enumerate(xs)]
        lo = [v - (eps if j == i else 0.0) for j, v in enumerate(xs)]
        out.append((f(*map(Var, hi)).value - f(*map(Var, lo)).value) / (2 * eps))
    return out


def h(x, y):
    return vsin(x * y) + x * vexp(y)


assert np.isclose(var_grad(lambda x: x * x)(3.0)[0], 6.0), "d(x x)/dx = 2x = 6: add both uses"
assert np.allclose(var_grad(h)(0.4, -1.2), central(h, [0.4, -1.2]), atol=1e-8), \
    "gradient of h must match central differences"
### BEGIN HIDDEN TESTS
got5 = var_grad(lambda x, y: x * 2.0)(1.0, 5.0)
assert got5 == (2.0, 0.0), f"f(x, y) = 2 x at (1, 5), y unused: expected (2.0, 0.0), got {got5}"


def long_chain(x):
    for _ in range(5000):
        x = x * 0.9999 + 0.001
    return x


got5 = var_grad(long_chain)(1.0)[0]
assert np.isclose(got5, 0.9999**5000), \
    f"5000 steps x <- 0.9999 x + 0.001: expected {0.9999 ** 5000:.6f}, got {got5!r}"
k = lambda a, b, c: vexp(a * b) * c + vsin(c * c - a)  # noqa: E731
got5, want5 = var_grad(k)(0.1, 0.2, 0.3), central(k, [0.1, 0.2, 0.3])
assert np.allclose(got5, want5, atol=1e-8), \
    (f"k(a, b, c) = exp(a b) c + sin(c c - a) at (0.1, 0.2, 0.3): expected "
     f"{np.round(want5, 6).tolist()} (central differences), got {got5}")
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 1.6 — the computation graph, with the cotangent on each edge
# `var_grad` keeps one number per node and forgets how it was assembled. Keep
# the pieces instead: every edge `parent → child` (the child used the parent)
# carries the cotangent $\bar g_\text{child}\,\partial\,\text{child}/\partial\,\text{parent}$,
# and a node's cotangent $\bar g$ is the **sum over the edges that leave it**
# ($\bar g = 1$ at the output).
#
# Write `edge_cotangents(end)`: return the list of triples
# `(parent, child, cotangent)`, one per edge, visiting the nodes in the order of
# `toposort(end, parents_of=lambda v: v.parents)` and, for each node, its
# parents in tuple order (`x * x` has **two** edges from `x`). A child's
# cotangent is complete when the walk reaches it (that is what the topological
# order guarantees), so each edge's value is known at that moment.
#
# <details><summary>Hint 1 (the idea)</summary>
#
# Compare your edges into `x` with the derivative of the grade cell: if their sum
# is off, some edge forgot what flowed into its child.
# </details>
#
# <details><summary>Hint 2 (the method)</summary>
#
# An edge carries the child's **total** cotangent (the sum over the edges that
# left the child, 1 at the output) times the local derivative — not 1 times it.
# </details>

# %% solution id=ex01_6 title="Cotangent on each edge" forbids="minimanc.autodiff.graph.computation_graph"  # noqa: E501
def edge_cotangents(end):
    ### BEGIN SOLUTION
    cot = {id(end): 1.0}
    edges = []
    for node in toposort(end, parents_of=lambda v: v.parents):
        g = cot.get(id(node), 0.0)
        for parent, local in zip(node.parents, node.local_grads):
            edges.append((parent, node, g * local))
            cot[id(parent)] = cot.get(id(parent), 0.0) + g * local
    return edges
    ### END SOLUTION

# %% grade id=ex01_6_tests points=4
x = Var(0.7)
s_ = vsin(x * x)
y = s_ + x
edges = edge_cotangents(y)
assert len(edges) == 5, f"5 edges expected (x*x counts twice), got {len(edges)}"
c = math.cos(0.49)
assert edges[0][0] is s_ and edges[0][1] is y, \
    "first edge: sin -> add (the output's edges come first, its parents in tuple order)"
assert edges[1][0] is x and edges[1][1] is y, "second edge: x -> add"
assert np.allclose([ct for _, _, ct in edges], [1.0, 1.0, c, 0.7 * c, 0.7 * c]), \
    "cotangents: 1, 1, cos(x^2), x cos(x^2), x cos(x^2)"
x_bar = sum(ct for p, _, ct in edges if p is x)
fd = (math.sin(0.7001 ** 2) + 0.7001 - math.sin(0.6999 ** 2) - 0.6999) / 0.0002
assert abs(x_bar - fd) < 1e-6, f"the edges leaving x must add up to df/dx = {fd:.6f}"
### BEGIN HIDDEN TESTS
a, b = Var(0.4), Var(-1.2)
ab = a * b
e_b = vexp(b)
sn = vsin(ab)
prod = a * e_b
h_out = sn + prod
got = [(p, ch, ct) for p, ch, ct in edge_cotangents(h_out)]
# the order of toposort, written out: add, multiply(a, e^b), exp, sin, multiply(a, b)
want = [(sn, h_out, 1.0), (prod, h_out, 1.0), (a, prod, math.exp(-1.2)), (e_b, prod, 0.4),
        (b, e_b, 0.4 * math.exp(-1.2)), (ab, sn, math.cos(-0.48)),
        (a, ab, math.cos(-0.48) * -1.2), (b, ab, math.cos(-0.48) * 0.4)]
assert len(got) == len(want), f"{len(want)} edges expected, got {len(got)}"
for k, ((p, ch, ct), (wp, wch, wct)) in enumerate(zip(got, want)):
    assert p is wp and ch is wch, f"edge {k}: wrong parent/child (toposort order, tuple order)"
    assert abs(ct - wct) < 1e-12, f"edge {k}: cotangent {wct:.6f} expected, got {ct:.6f}"
chain_x = Var(1.0)
node = chain_x
for _ in range(3000):
    node = node * 0.999
chain_edges = edge_cotangents(node)
assert len(chain_edges) == 6000, \
    f"3000 products (the constant is a Var too): expected 6000 edges, got {len(chain_edges)}"
into_x = [ct for p, _, ct in chain_edges if p is chain_x]
assert len(into_x) == 1 and abs(into_x[0] - 0.999 ** 3000) < 1e-12, \
    f"0.999^3000 x: expected one edge from x carrying {0.999 ** 3000:.6g}, got {into_x}"
lone = Var(2.0)
got6 = edge_cotangents(lone)
assert got6 == [], f"a single input: expected no edges, got {got6}"
### END HIDDEN TESTS

# %% [markdown]
# The library's `computation_graph(f, *args)` does the same on arrays (every
# primitive of `minimanc.autodiff.numpy`, conv included) and prints one line per
# edge; `minimanc.viz.graph.plot_graph(graph, ax)` draws it (see the tutorial).

# %%
g_lib = computation_graph(lambda x, y: anp.sin(x * y) + x * anp.exp(y), np.array(0.4),
                          np.array(-1.2))
print(g_lib)
gx_lib, gy_lib = g_lib.gradients()
assert np.isclose(gx_lib, np.cos(-0.48) * -1.2 + np.exp(-1.2))
assert np.isclose(gy_lib, np.cos(-0.48) * 0.4 + 0.4 * np.exp(-1.2))

# %% [markdown]
# ## The same, with the library
# `minimanc.autodiff.grad` does on arrays what `var_grad` does on scalars, with
# the VJPs you wrote above (they are in `minimanc/autodiff/numpy.py`). From here
# on the notebooks use the library, so they run even if an exercise above is
# unfinished.

# %%
def h_arrays(x, y):
    return anp.sum(anp.sin(x * y) + x * anp.exp(y))


gx, gy = grad(h_arrays, argnums=(0, 1))(np.array([0.4]), np.array([-1.2]))
expected = (np.cos(0.4 * -1.2) * -1.2 + np.exp(-1.2), np.cos(0.4 * -1.2) * 0.4 + 0.4 * np.exp(-1.2))
assert np.allclose([gx[0], gy[0]], expected)
print(f"dh/dx = {gx[0]:.6f}, dh/dy = {gy[0]:.6f}")

# %% [markdown]
# ## Exercise 1.7 — a primitive the tutorial never differentiated: a linear solve
# `np.linalg.solve(A, b)` returns $x$ with $A x = b$ ($A$ square and invertible,
# $b$ of shape `(n,)` or `(n, k)`). Make it a primitive and write its two VJPs,
# `solve_vjp_A(g, ans, A, b)` and `solve_vjp_b(g, ans, A, b)` (`ans` is $x$), each
# with the shape of its argument. Do not form $A^{-1}$: a solve is cheaper and
# more accurate. Two grade cells: the cotangent of $b$ (1 point), of $A$ (2 points).
#
# <details><summary>Hint 1 (the idea)</summary>
#
# Differentiate the equation $A x = b$ itself, not a formula for $x$: a small change
# $dA$, $db$ moves $x$ by a $dx$ that satisfies one linear equation.
# </details>
#
# <details><summary>Hint 2 (the method)</summary>
#
# A VJP is the map $g \mapsto$ the coefficients of $db$ (and of $dA$) in
# $\langle g, dx\rangle$. Write $dx$ from Hint 1, move the matrix that multiplies
# it to the other side of the inner product (it becomes its transpose), and read
# off both coefficients; one solve with $A^\top$ serves both VJPs.
# </details>

# %% solution id=ex01_7 title="VJPs of a linear solve"
def solve_vjp_b(g, ans, A, b):
    ### BEGIN SOLUTION
    return np.linalg.solve(A.T, g)
    ### END SOLUTION


def solve_vjp_A(g, ans, A, b):
    ### BEGIN SOLUTION
    lam = np.linalg.solve(A.T, g)
    return -(np.outer(lam, ans) if ans.ndim == 1 else lam @ ans.T)
    ### END SOLUTION

# %% grade id=ex01_7_b_tests points=1
def fd_check(f, x, case):
    """check_grads on argument 0, its failure restated with the case."""
    try:
        check_grads(f, x, argnums=0, verbose=False)
    except AssertionError as exc:
        raise AssertionError(f"{case}: expected the central differences, got: "
                             f"{' '.join(str(exc).split())[:160]}") from None


my_solve = primitive(np.linalg.solve)
defvjp(my_solve, None, solve_vjp_b)
A7 = np.array([[3.0, 1.0], [-1.0, 2.0]])  # not symmetric: A and its transpose differ
b7 = np.array([1.0, -1.0])
fd_check(lambda b: anp.sum(my_solve(A7, b) ** 2), b7, "A 2 x 2, b (2,), the cotangent of b")
### BEGIN HIDDEN TESTS
test_rng = np.random.default_rng(170)  # the tests' own draws, not the notebook's rng
for shape in [(4,), (4, 3), (1,), (1, 2)]:
    n = shape[0]
    Ah = test_rng.normal(size=(n, n)) + n * np.eye(n)
    bh = test_rng.normal(size=shape)
    gh = test_rng.normal(size=shape)
    got = solve_vjp_b(gh, np.linalg.solve(Ah, bh), Ah, bh)
    assert np.shape(got) == shape, \
        f"b of shape {shape}: expected the shape of b, {shape}, got {np.shape(got)}"
    fd_check(lambda b, A=Ah, g=gh: anp.sum(my_solve(A, b) * g), bh, f"b of shape {shape}")
### END HIDDEN TESTS

# %% grade id=ex01_7_tests points=2
def fd_check(f, x, case):
    """check_grads on argument 0, its failure restated with the case."""
    try:
        check_grads(f, x, argnums=0, verbose=False)
    except AssertionError as exc:
        raise AssertionError(f"{case}: expected the central differences, got: "
                             f"{' '.join(str(exc).split())[:160]}") from None


my_solve_A = primitive(np.linalg.solve)
defvjp(my_solve_A, solve_vjp_A, None)
A7 = np.array([[3.0, 1.0], [-1.0, 2.0]])  # not symmetric: A and its transpose differ
b7 = np.array([1.0, -1.0])
fd_check(lambda A: anp.sum(my_solve_A(A, b7) ** 2), A7, "A 2 x 2, b (2,), the cotangent of A")
### BEGIN HIDDEN TESTS
test_rng = np.random.default_rng(171)
for shape in [(4,), (4, 3), (1,), (3, 1)]:
    n = shape[0]
    Ah = test_rng.normal(size=(n, n)) + n * np.eye(n)
    bh = test_rng.normal(size=shape)
    gh = test_rng.normal(size=shape)
    got = solve_vjp_A(gh, np.linalg.solve(Ah, bh), Ah, bh)
    assert np.shape(got) == (n, n), \
        f"b of shape {shape}: expected the shape of A, {(n, n)}, got {np.shape(got)}"
    fd_check(lambda A, b=bh, g=gh: anp.sum(my_solve_A(A, b) * g), Ah,
             f"A {n} x {n}, b of shape {shape}")
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 1.8 — an open experiment: the step of a finite difference
# Every gradient check of this chapter compares with a finite difference at
# $\varepsilon = 10^{-6}$. Is that a good step? Experiment with $f = \exp$ at $x = 1$
# (where $f' = e$), in float64:
#
# 1. `fd_errors(eps)`: return `(forward, central)`, the absolute errors
#    $|(f(1+\varepsilon) - f(1))/\varepsilon - e|$ and
#    $|(f(1+\varepsilon) - f(1-\varepsilon))/(2\varepsilon) - e|$ as floats (use `math.exp`).
# 2. `best_steps()`: return `(eps_forward, eps_central)`, the steps you would use
#    for each formula, found by your own scan (plot the errors over
#    $\varepsilon = 10^{-12} \dots 10^{-1}$ on log–log axes if you like).
#
# The grade cell recomputes the errors at your steps with its own formulas: the
# forward error must be below $2\cdot 10^{-7}$ and the central one below
# $10^{-9}$ (3 points).

# %% solution id=ex01_8 title="The step of a finite difference"
def fd_errors(eps):
    ### BEGIN SOLUTION
    forward = (math.exp(1.0 + eps) - math.exp(1.0)) / eps
    central = (math.exp(1.0 + eps) - math.exp(1.0 - eps)) / (2.0 * eps)
    return abs(forward - math.e), abs(central - math.e)
    ### END SOLUTION


def best_steps():
    ### BEGIN SOLUTION
    grid = np.logspace(-12, -1, 221)
    errors = np.array([fd_errors(float(e)) for e in grid])
    # the noisy minimum of each column; its neighbourhood decides, not one lucky point
    smooth = np.array([np.convolve(errors[:, k], np.ones(9) / 9, mode="same") for k in (0, 1)])
    return float(grid[np.argmin(smooth[0])]), float(grid[np.argmin(smooth[1])])
    ### END SOLUTION

# %% grade id=ex01_8_tests points=3
got8 = fd_errors(1e-3)
want8 = (abs((math.exp(1.001) - math.e) / 1e-3 - math.e),
         abs((math.exp(1.001) - math.exp(0.999)) / 2e-3 - math.e))
assert isinstance(got8, tuple) and len(got8) == 2, f"expected a pair of floats, got {got8!r}"
assert all(math.isclose(g, w, rel_tol=1e-6) for g, w in zip(got8, want8)), \
    f"eps = 1e-3: expected (forward, central) = ({want8[0]:.6g}, {want8[1]:.6g}), got {got8}"
eps_f, eps_c = best_steps()
err_f = abs((math.exp(1.0 + eps_f) - math.e) / eps_f - math.e)
err_c = abs((math.exp(1.0 + eps_c) - math.exp(1.0 - eps_c)) / (2.0 * eps_c) - math.e)
assert err_f < 2e-7, \
    f"forward difference at eps = {eps_f:.3g}: expected an error < 2e-7, got {err_f:.3g}"
assert err_c < 1e-9, \
    f"central difference at eps = {eps_c:.3g}: expected an error < 1e-9, got {err_c:.3g}"
### BEGIN HIDDEN TESTS
for eps_h in (1e-1, 1e-2, 3e-3):
    want_h = (abs((math.exp(1.0 + eps_h) - math.e) / eps_h - math.e),
              abs((math.exp(1.0 + eps_h) - math.exp(1.0 - eps_h)) / (2.0 * eps_h) - math.e))
    got_h = fd_errors(eps_h)
    assert all(math.isclose(g, w, rel_tol=1e-6) for g, w in zip(got_h, want_h)), \
        f"eps = {eps_h}: expected ({want_h[0]:.6g}, {want_h[1]:.6g}), got {got_h}"
assert type(eps_f) is float and type(eps_c) is float, \
    f"expected two floats, got {type(eps_f).__name__}, {type(eps_c).__name__}"
assert eps_f < eps_c, \
    f"expected the forward step below the central one, got {eps_f:.3g} >= {eps_c:.3g}"
### END HIDDEN TESTS

# %% [markdown]
# **Written question (graded by hand, 2 points).** Why does the error grow again
# when $\varepsilon$ gets small? Estimate the best step of each formula from the two
# sources of error (in terms of the machine epsilon $\approx 2.2\cdot10^{-16}$) and
# compare with what you found. Is $10^{-6}$ a sensible default for `check_grads`?

# %% [markdown] answer id=ex01_w title="Truncation against rounding" points=2
# ### BEGIN SOLUTION
# Two errors compete. Truncation: Taylor gives $f''\varepsilon/2$ for the forward
# difference and $f'''\varepsilon^2/6$ for the central one. Rounding: $f(1\pm\varepsilon)$
# carry a relative error $\approx u = 2.2\cdot10^{-16}$, so the difference carries
# $\approx u|f|$, divided by $\varepsilon$: it grows like $u|f|/\varepsilon$. Minimising
# $f''\varepsilon/2 + u f/\varepsilon$ gives $\varepsilon \approx \sqrt{u} \approx 10^{-8}$
# (error $\approx 10^{-8}$); minimising $f'''\varepsilon^2/6 + u f/\varepsilon$ gives
# $\varepsilon \approx u^{1/3} \approx 6\cdot10^{-6}$ (error $\approx 10^{-11}$), as the scan
# shows. $10^{-6}$ is close to the central optimum, with errors far below the
# `check_grads` tolerances ($10^{-6}$ absolute); for a forward difference it would be
# ≈ 100× too large.
# ### END SOLUTION

# %% [markdown]
# ## Your figure
# The tutorial's computation graph of $h(x, y) = \sin(xy) + x e^y$ at $(0.4, -1.2)$,
# drawn twice: by the library's `computation_graph` (left) and from **your**
# `edge_cotangents` of exercise 1.6 on the scalar engine (right). Every edge label of
# yours must equal the library's; a wrong cotangent shows as a different label, a
# function that still raises is named in the title.

# %%
xv, yv = Var(0.4), Var(-1.2)
hv = vsin(xv * yv) + xv * vexp(yv)
plot_edge_cotangents(edge_cotangents, hv, {id(xv): "arg0", id(yv): "arg1"}, g_lib)
plt.show()
