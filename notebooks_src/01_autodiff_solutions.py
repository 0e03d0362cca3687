# %% [markdown]
# # Chapter 1 — Exercises: build reverse-mode autodiff
#
# Modules built in this chapter: `minimanc.autodiff` (its `__init__.py`, `numpy.py`,
# `check.py`), its pytrees `minimanc.tree` and `minimanc.engine`. Read
# `tutorials/01_autodiff.ipynb` first.
#
# You will write the pieces of a reverse-mode engine yourself: summing a
# cotangent back over broadcasting, the vector-Jacobian products (VJPs) of
# `multiply`, `exp`, `sum` and `matmul`, the topological sort of the tape,
# `grad` itself for a small scalar engine, and finally the computation graph
# with the cotangent that flows along each of its edges. Every grade cell checks your
# code against central differences or the library. Replace each
# `raise NotImplementedError(...)` with your code and run the grade cell below
# it; `minimanc grade exercises/01_autodiff.ipynb` scores the whole notebook.

# %%
import math

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

rng = np.random.default_rng(0)

# %% [markdown]
# ## Exercise 1.1 — sum a cotangent back over broadcasting
# When `x` of shape `shape` is broadcast to the shape of `g` (new leading axes,
# and axes of size one stretched), every element of `x` is copied several
# times. The VJP of a copy is a sum: return `g` summed back to `shape`.
# Example: `shape=(3, 1)`, `g.shape == (2, 3, 4)` → sum over axis 0 (new) and
# axis 2 (stretched, keeping it with size one).

# %% solution id=ex01_1 title="Unbroadcast a cotangent" forbids="minimanc.autodiff.unbroadcast"  # noqa: E501
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
assert np.isclose(my_unbroadcast((), g), g.sum()), "shape (): the sum of all of g"
# the sums written out by hand: new leading axes go, stretched axes of size one stay
expected = {(1, 1, 4): g.sum(axis=(0, 1), keepdims=True),
            (2, 1, 1): g.sum(axis=(1, 2), keepdims=True),
            (1,): np.array([g.sum()]),
            (1, 3, 1): g.sum(axis=(0, 2), keepdims=True)}
for shape, want in expected.items():
    got = my_unbroadcast(shape, g)
    assert np.shape(got) == shape and np.allclose(got, want), f"shape {shape}: wrong sum"
assert np.allclose(my_unbroadcast((1, 3, 1), g)[0, :, 0], [g[:, i].sum() for i in range(3)]), \
    "(1, 3, 1): entry i is the sum of g[:, i]"
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
check_grads(lambda x: anp.sum(my_sum(x * x, axis=(0, 2), keepdims=True) ** 2),
            rng.normal(size=(2, 3, 2)), verbose=False)
check_grads(lambda x: anp.sum(my_sum(x, axis=-1) * np.arange(2.0)), rng.normal(size=(2, 3)),
            verbose=False)
report = check_grads(lambda a, b: my_sum(my_multiply(a, b) ** 2), rng.normal(size=(2, 1, 3)),
                     rng.normal(size=(4, 1)), verbose=False)
assert report.passed, "gradient of sum((a b)^2) must match central differences"
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 1.3 — VJP of a matrix product
# For $Y = AB$ with $A \in \mathbb{R}^{n\times k}$, $B \in \mathbb{R}^{k\times m}$ and
# cotangent $\bar Y$, derive $\bar A$ and $\bar B$ from
# $Y_{ij} = \sum_l A_{il} B_{lj}$ (hint: $\partial L/\partial A_{il} =
# \sum_j \bar Y_{ij} B_{lj}$). Return both as a tuple. Never build the
# Jacobian.

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
assert np.allclose(ref_A, mine[0]) and np.allclose(ref_B, mine[1]), \
    "grad through my_matmul: W B^T, A^T W"
gA, gB = matmul_vjps(W, A, B)
assert np.allclose(gA, ref_A) and np.allclose(gB, ref_B), "matmul_vjps(W, A, B) = (W B^T, A^T W)"
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

# %% solution id=ex01_4 title="Topological sort" forbids="minimanc.autodiff.toposort"  # noqa: E501
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
assert deep_order[-1] is x and len(deep_order) == 1 + 4 * 10_000, \
    "a chain of 10,000 steps: 40,001 nodes, the input last"
assert [id(n) for n in topo_order(y)] == [id(n) for n in order], "deterministic"
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
assert var_grad(lambda x, y: x * 2.0)(1.0, 5.0) == (2.0, 0.0), "(2.0, 0.0): y is unused"


def long_chain(x):
    for _ in range(5000):
        x = x * 0.9999 + 0.001
    return x


assert np.isclose(var_grad(long_chain)(1.0)[0], 0.9999**5000), "0.9999^5000 through 5000 steps"
k = lambda a, b, c: vexp(a * b) * c + vsin(c * c - a)  # noqa: E731
assert np.allclose(var_grad(k)(0.1, 0.2, 0.3), central(k, [0.1, 0.2, 0.3]), atol=1e-8), \
    "gradient of k must match central differences"
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
# *Hint.* If the input's edges do not add up to the derivative, check that you
# multiply the child's **total** cotangent (not 1) by the local derivative.

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
assert len(chain_edges) == 6000, "each product has two edges (the constant is a Var too)"
into_x = [ct for p, _, ct in chain_edges if p is chain_x]
assert len(into_x) == 1 and abs(into_x[0] - 0.999 ** 3000) < 1e-12, "d/dx of 0.999^3000 x"
lone = Var(2.0)
assert edge_cotangents(lone) == [], "a single input has no edges"
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
