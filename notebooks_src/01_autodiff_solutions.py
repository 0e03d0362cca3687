# %% [markdown]
# # Chapter 1 — Exercises: build reverse-mode autodiff
#
# Modules built in this chapter: `minimanc.autodiff` (its `__init__.py`, `numpy.py`,
# `check.py`), its pytrees `minimanc.tree` and `minimanc.engine`. Read
# `tutorials/01_autodiff.ipynb` first.
#
# You will derive the pieces of a reverse-mode engine the tutorial does not print:
# the VJPs of `np.tile`, `cumsum`, `max` (with ties) and `sort`, and of a batched,
# broadcast matrix product; the topological sort of the tape; forward mode on the
# same tape (1.5); the computation graph with the cotangent that flows along each
# of its edges (1.6); the VJPs of a linear solve (1.7); and an experiment on the
# step of a finite difference (1.8) with a written answer, graded by hand. The
# last cell draws the chapter's graph figure from *your*
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
# ## Exercise 1.1 — the VJP of `np.tile`
# Broadcasting copies each *element* along new or stretched axes, and its VJP sums
# the copies back (tutorial section 3). `np.tile(x, reps)` copies the *whole array*
# as blocks instead: `np.tile([1, 2], 3)` is `[1, 2, 1, 2, 1, 2]`, and
# `np.tile(x, (2, 3))` lays 2 × 3 copies of a 2-D `x` side by side. NumPy's rules:
# when `reps` is shorter than `x.ndim` it is padded with ones in front; when it is
# longer, `x` first gets leading axes of size one.
#
# Write `tile_vjp(g, x_shape, reps)`: the cotangent of `x` (shape `x_shape`) for the
# cotangent `g` of `np.tile(x, reps)`. Use array operations, not a loop over
# elements. The autodiff engine is switched off while this exercise is graded.
#
# <details><summary>Hint 1 (the idea)</summary>
#
# Which entries of the tiled array are copies of `x[i]`? In one dimension they are
# `n` apart, not next to each other as with `np.repeat`.
# </details>
#
# <details><summary>Hint 2 (the method)</summary>
#
# Give every axis of `g` two axes, (which copy, where in `x`), by one reshape; the
# copies are then one axis each, to be summed.
# </details>

# %% solution id=ex01_1 title="The VJP of np.tile" forbids="minimanc.autodiff.reverse.backward"
def tile_vjp(g, x_shape, reps):
    ### BEGIN SOLUTION
    reps = (reps,) if np.ndim(reps) == 0 else tuple(reps)
    d = max(len(reps), len(x_shape))
    shape = (1,) * (d - len(x_shape)) + tuple(x_shape)
    reps = (1,) * (d - len(reps)) + reps
    pairs = [n for pair in zip(reps, shape) for n in pair]   # (copy, position) per axis
    summed = np.asarray(g).reshape(pairs).sum(axis=tuple(range(0, 2 * d, 2)))
    return summed.reshape(x_shape)
    ### END SOLUTION

# %% grade id=ex01_1_tests points=2
got1 = tile_vjp(np.arange(6.0), (2,), 3)
assert np.shape(got1) == (2,), f"x of shape (2,), reps 3: expected shape (2,); got {np.shape(got1)}"
assert np.allclose(got1, [6.0, 9.0]), \
    f"x of shape (2,), reps 3, g = [0, 1, ..., 5]: expected [6, 9]; got {got1}"
got1 = tile_vjp(np.arange(8.0).reshape(4, 2), (2, 2), (2, 1))
assert np.allclose(got1, [[4.0, 6.0], [8.0, 10.0]]), (
    f"x (2, 2), reps (2, 1), g = arange(8) as (4, 2): expected [[4, 6], [8, 10]]; "
    f"got {np.asarray(got1).tolist()}")
### BEGIN HIDDEN TESTS
test_rng = np.random.default_rng(110)  # the tests' own draws, not the notebook's rng
for shape, reps in [((3,), (2, 4)), ((2, 3), 2), ((2, 1, 3), (3, 1, 2)), ((4, 2), (1, 1)),
                    ((2, 3), (2, 2, 1, 3)), ((), (3, 2)), ((5,), ())]:
    xh = test_rng.normal(size=shape)
    gh = test_rng.normal(size=np.tile(xh, reps).shape)
    got = np.asarray(tile_vjp(gh, shape, reps))
    assert got.shape == shape, f"x {shape}, reps {reps}: expected shape {shape}; got {got.shape}"
    # the adjoint identity <tile(x), g> = <x, tile_vjp(g)>, and every entry by its copies
    lhs, rhs = float(np.sum(np.tile(xh, reps) * gh)), float(np.sum(xh * got))
    assert np.isclose(lhs, rhs), \
        f"x {shape}, reps {reps}: expected <tile(x), g> = <x, vjp> = {lhs:.6f}; got {rhs:.6f}"
    for idx in np.ndindex(*shape):
        e = np.zeros(shape)
        e[idx] = 1.0
        want = float(np.sum(np.tile(e, reps) * gh))
        assert np.isclose(got[idx], want), \
            f"x {shape}, reps {reps}, entry {idx}: expected {want:.6f}; got {got[idx]:.6f}"
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 1.2 — VJPs of `cumsum`, `max` and `sort`
# Three primitives the tutorial never differentiated. A VJP receives the output
# cotangent `g`, the forward result `ans` and the forward arguments, and returns
# the cotangent of `x`, **with the shape of `x`**. Work each one out from what the
# forward pass does with every entry of `x`:
#
# * `cumsum_vjp(g, ans, x, axis)`: `np.cumsum(x, axis)` (an integer `axis`);
# * `max_vjp(g, ans, x, axis, keepdims=False)`: `np.max(x, axis, keepdims)` (an
#   integer `axis`); where several entries tie for the maximum, they **share** its
#   cotangent equally;
# * `sort_vjp(g, ans, x)`: `np.sort(x, axis=-1)`.
#
# The grade cell registers them on fresh primitives with `defvjp` and checks the
# gradients with `check_grads` and on hand-made cases. The library's own VJPs of
# `cumsum` and `max` are switched off while this exercise is graded.
#
# <details><summary>Hint 1 (the idea)</summary>
#
# A VJP asks, for every entry $x_j$: which outputs did it enter, and with what local
# derivative? For `cumsum` that is many outputs, for `max` at most one (or a tie),
# for `sort` exactly one.
# </details>
#
# <details><summary>Hint 2 (the method)</summary>
#
# Write each answer first for a 1-D `x` of three entries, by hand: which $g_i$ reach
# $\bar x_j$? Then find NumPy operations that compute the same for every $j$ at once,
# along `axis`, without a Python loop over entries. `sort` moved every entry somewhere:
# the cotangent must go back the same way. Check each VJP against central differences
# on random `x`, and `max` on a tie made by hand (the shares must add up to `g`).
# </details>

# %% solution id=ex01_2 title="VJPs of cumsum, max and sort" forbids="minimanc.autodiff.reductions._cumsum_vjp,minimanc.autodiff.reductions._chooser_vjp"  # noqa: E501
def cumsum_vjp(g, ans, x, axis):
    ### BEGIN SOLUTION
    return np.flip(np.cumsum(np.flip(g, axis), axis), axis)
    ### END SOLUTION


def max_vjp(g, ans, x, axis, keepdims=False):
    ### BEGIN SOLUTION
    if not keepdims:
        g, ans = np.expand_dims(g, axis), np.expand_dims(ans, axis)
    hit = x == ans
    return g * hit / hit.sum(axis=axis, keepdims=True)
    ### END SOLUTION


def sort_vjp(g, ans, x):
    ### BEGIN SOLUTION
    out = np.zeros(np.shape(x))
    np.put_along_axis(out, np.argsort(x, axis=-1), g, axis=-1)
    return out
    ### END SOLUTION

# %% grade id=ex01_2_tests points=3
@primitive
def my_cumsum(x, axis):
    return np.cumsum(x, axis=axis)


@primitive
def my_max(x, axis, keepdims=False):
    return np.max(x, axis=axis, keepdims=keepdims)


@primitive
def my_sort(x):
    return np.sort(x, axis=-1)


defvjp(my_cumsum, cumsum_vjp)
defvjp(my_max, max_vjp)
defvjp(my_sort, sort_vjp)
got2 = cumsum_vjp(np.array([1.0, 2.0, 3.0]), None, np.zeros(3), 0)
assert np.allclose(got2, [6.0, 5.0, 3.0]), \
    f"cumsum of 3 entries, g = [1, 2, 3]: expected [6, 5, 3]; got {got2}"
x2 = np.array([[1.0, 3.0, 3.0], [2.0, 0.0, 1.0]])
got2 = max_vjp(np.array([6.0, 4.0]), x2.max(axis=1), x2, 1)
assert np.allclose(got2, [[0.0, 3.0, 3.0], [4.0, 0.0, 0.0]]), (
    f"max over axis 1 of [[1, 3, 3], [2, 0, 1]] (a tie in row 0), g = [6, 4]: expected "
    f"[[0, 3, 3], [4, 0, 0]]; got {np.asarray(got2).tolist()}")
got2 = sort_vjp(np.array([10.0, 20.0, 30.0]), None, np.array([3.0, 1.0, 2.0]))
assert np.allclose(got2, [30.0, 10.0, 20.0]), \
    f"sort of [3, 1, 2], g = [10, 20, 30]: expected [30, 10, 20]; got {got2}"
check_grads(lambda x: anp.sum(my_cumsum(x, 1) ** 2), rng.normal(size=(2, 4)), verbose=False)
check_grads(lambda x: anp.sum(my_max(x, 0) ** 3), rng.normal(size=(3, 2)), verbose=False)
check_grads(lambda x: anp.sum(my_sort(x) * np.arange(5.0)), rng.normal(size=(2, 5)),
            verbose=False)
### BEGIN HIDDEN TESTS
test_rng = np.random.default_rng(120)  # the tests' own draws, not the notebook's rng
cases2 = [("cumsum over axis 0 of (4, 3)", lambda x: anp.sum(my_cumsum(x, 0) * np.arange(12.0)
                                                               .reshape(4, 3)),
           test_rng.normal(size=(4, 3))),
          ("cumsum over axis -1 of (2, 3, 4)", lambda x: anp.sum(my_cumsum(x, -1) ** 2),
           test_rng.normal(size=(2, 3, 4))),
          ("max over axis 2, keepdims, (2, 3, 4)",
           lambda x: anp.sum(my_max(x, 2, True) * np.arange(6.0).reshape(2, 3, 1)),
           test_rng.normal(size=(2, 3, 4))),
          ("max over axis -2 of (3, 4, 2)", lambda x: anp.sum(anp.sin(my_max(x, -2))),
           test_rng.normal(size=(3, 4, 2))),
          ("sort of (3, 2, 6)", lambda x: anp.sum(my_sort(x) ** 2 * np.arange(6.0)),
           test_rng.normal(size=(3, 2, 6)))]
for case2, f2, x2h in cases2:
    try:
        check_grads(f2, x2h, verbose=False)
    except AssertionError as exc:
        raise AssertionError(f"{case2}: expected the central differences, got: "
                             f"{' '.join(str(exc).split())[:160]}") from None
tie = np.array([[2.0, 2.0, 2.0, 1.0]])
got = np.asarray(max_vjp(np.array([[9.0]]), tie.max(axis=1, keepdims=True), tie, 1, True))
assert np.shape(got) == (1, 4) and np.allclose(got, [[3.0, 3.0, 3.0, 0.0]]), \
    f"a three-way tie, keepdims, g = 9: expected [[3, 3, 3, 0]]; got {got.tolist()}"
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 1.3 — the VJP of a batched matrix product
# The tutorial gives the VJPs of $Y = AB$ for two matrices. `np.matmul` (`@`) also
# multiplies **stacks** of matrices: `A` of shape `(..., n, k)` times `B` of shape
# `(..., k, m)`, the leading (batch) axes broadcast against each other — a batch of
# inputs `(5, 2, 3)` times one weight matrix `(3, 4)`, or `(2, 1, n, k)` times
# `(3, k, m)`. Write `batched_matmul_vjps(g, A, B)` returning `(A_bar, B_bar)`, the
# cotangents of `A` and `B` **with their shapes**, for both at least 2-D. Never build
# the Jacobian. The library's VJPs of `matmul` and `einsum` are switched off while
# this exercise is graded.
#
# <details><summary>Hint 1 (the idea)</summary>
#
# Each matrix of the stack is an ordinary product, with the tutorial's rule. A
# matrix reused by several products of the batch (a broadcast one) receives the
# cotangents of all its uses.
# </details>
#
# <details><summary>Hint 2 (the method)</summary>
#
# Write the tutorial's two rules for one matrix of the stack, then ask what "transpose"
# must mean for a stack, and what shape your result has when an operand was broadcast:
# which axes of the cotangent belong to copies that were never stored? Check the shapes
# first (`(5, 2, 3) @ (3, 4)` must give a `(3, 4)` cotangent for the weights), then one
# entry of each against a central difference.
# </details>

# %% solution id=ex01_3 title="VJP of a batched matmul" forbids="minimanc.autodiff.numpy._matmul_vjp_x,minimanc.autodiff.numpy._matmul_vjp_y,minimanc.autodiff.numpy._einsum_vjp"  # noqa: E501
def batched_matmul_vjps(g, A, B):
    ### BEGIN SOLUTION
    return (unbroadcast(A, g @ np.swapaxes(B, -1, -2)),
            unbroadcast(B, np.swapaxes(A, -1, -2) @ g))
    ### END SOLUTION

# %% grade id=ex01_3_tests points=2
my_matmul = primitive(np.matmul)
defvjp(my_matmul, lambda g, ans, A, B: batched_matmul_vjps(g, A, B)[0],
       lambda g, ans, A, B: batched_matmul_vjps(g, A, B)[1])
A3, B3 = np.ones((4, 2, 5)), rng.normal(size=(5, 3))
gA, gB = batched_matmul_vjps(np.ones((4, 2, 3)), A3, B3)
assert np.shape(gA) == (4, 2, 5) and np.shape(gB) == (5, 3), \
    f"A (4, 2, 5), B (5, 3): expected shapes (4, 2, 5), (5, 3); got {np.shape(gA)}, {np.shape(gB)}"
assert np.allclose(gB, 8.0), \
    f"A = ones (4, 2, 5), B (5, 3), g = ones (4, 2, 3): expected B_bar = 8 everywhere; got {gB}"
check_grads(lambda A, B: anp.sum(anp.tanh(my_matmul(A, B))), rng.normal(size=(3, 2, 4)),
            rng.normal(size=(4, 2)), verbose=False)
### BEGIN HIDDEN TESTS
test_rng = np.random.default_rng(130)  # the tests' own draws, not the notebook's rng
for sa, sb in [((3, 4), (4, 2)), ((2, 1, 3, 4), (5, 4, 2)), ((3, 4), (6, 4, 2)),
               ((1, 2, 3), (4, 3, 5)), ((2, 3, 4), (2, 4, 1))]:
    Ah, Bh = test_rng.normal(size=sa), test_rng.normal(size=sb)
    Wh = test_rng.normal(size=np.matmul(Ah, Bh).shape)
    gA, gB = batched_matmul_vjps(Wh, Ah, Bh)
    # d/dA sum((A @ B) * W), entry by entry with central differences
    for name, arg, got in (("A", Ah, gA), ("B", Bh, gB)):
        assert np.shape(got) == arg.shape, \
            f"A {sa}, B {sb}: expected the cotangent of {name} of shape {arg.shape}; got " \
            f"{np.shape(got)}"
        want = np.zeros(arg.shape)
        for idx in np.ndindex(*arg.shape):
            e = np.zeros(arg.shape)
            e[idx] = 1e-6
            hi = (Ah + e, Bh) if name == "A" else (Ah, Bh + e)
            lo = (Ah - e, Bh) if name == "A" else (Ah, Bh - e)
            want[idx] = (np.sum(np.matmul(*hi) * Wh) - np.sum(np.matmul(*lo) * Wh)) / 2e-6
        err = np.abs(np.asarray(got) - want).max()
        assert err < 1e-6, f"A {sa}, B {sb}, the cotangent of {name}: max error {err:.3g}"
### END HIDDEN TESTS

# %% [markdown]
# ## A scalar engine for exercises 1.4–1.6
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
assert len(deep_order) == 1 + 4 * 10_000, \
    f"a chain of 10,000 steps: expected 40,001 nodes, got {len(deep_order)}"
assert deep_order[-1] is x, \
    f"a chain of 10,000 steps: expected the input last, got {deep_order[-1]}"
again = topo_order(y)
assert [id(n) for n in again] == [id(n) for n in order], \
    f"the same graph twice: expected the same order, got {order} then {again}"
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 1.5 — forward mode on the tape
# Reverse mode (tutorial sections 4–5) runs the chain rule from the output back
# and gives the derivative of one output with respect to every input. **Forward
# mode** runs it the other way, from the inputs to the outputs: choose a direction
# $t$ in input space, and carry along every node the derivative of its value in
# that direction, $\frac{d}{d\varepsilon}\,\text{node}(x + \varepsilon t)$ at
# $\varepsilon = 0$. One forward sweep gives the directional derivative of *every*
# output at once.
#
# Write `var_jvp(f, xs, tangents)`: wrap the floats `xs` in `Var`s, run `f` on them
# (it returns one `Var` or a tuple of `Var`s), and return `(values, derivatives)`,
# two tuples with one float per output: the outputs' values and their derivatives
# in the direction `tangents`. Use the recorded tape: each node's `parents` and
# `local_grads` (the library's `toposort(end, parents_of=lambda v: v.parents)` orders
# the nodes below one output). Constants inside `f` become `Var`s too.
#
# <details><summary>Hint 1 (the idea)</summary>
#
# Which nodes know their tangent before anything is computed, and what does a node
# need from its parents to know its own? In which order must the nodes be visited?
# </details>
#
# <details><summary>Hint 2 (the method)</summary>
#
# Keep a dictionary `id(node) → tangent`, seeded at the inputs; every other leaf is a
# constant. Visit each output's nodes in the reverse of `toposort`'s order (each node
# after its parents) and apply the chain rule with the local derivatives; nodes
# shared by two outputs are computed once.
# </details>

# %% solution id=ex01_5 title="Forward mode on the tape"
def var_jvp(f, xs, tangents):
    ### BEGIN SOLUTION
    inputs = [Var(x) for x in xs]
    out = f(*inputs)
    outs = out if isinstance(out, tuple) else (out,)
    tangent = {id(v): float(t) for v, t in zip(inputs, tangents)}
    for end in outs:
        for node in reversed(toposort(end, parents_of=lambda v: v.parents)):
            if id(node) not in tangent:
                tangent[id(node)] = sum(local * tangent[id(parent)] for parent, local
                                        in zip(node.parents, node.local_grads))
    return tuple(v.value for v in outs), tuple(tangent[id(v)] for v in outs)
    ### END SOLUTION

# %% grade id=ex01_5_tests points=3
def h5(x, y):
    return x * y, vsin(x) + 2.0


values5, derivs5 = var_jvp(h5, (0.4, -1.2), (1.0, 0.0))
assert np.allclose(values5, (-0.48, math.sin(0.4) + 2.0)), \
    f"h(x, y) = (x y, sin x + 2) at (0.4, -1.2): expected values (-0.48, 2.3894); got {values5}"
assert np.allclose(derivs5, (-1.2, math.cos(0.4))), (
    f"h at (0.4, -1.2) in the direction (1, 0): expected derivatives (-1.2, 0.9211); "
    f"got {derivs5}")
_, derivs5 = var_jvp(lambda x: x * x, (3.0,), (1.0,))
assert np.allclose(derivs5, (6.0,)), f"x * x at 3 in the direction 1: expected (6,); got {derivs5}"
### BEGIN HIDDEN TESTS
def central5(f, xs, ts, eps=1e-6):
    """Directional central differences of every output of f (on Vars)."""
    hi = f(*[Var(x + eps * t) for x, t in zip(xs, ts)])
    lo = f(*[Var(x - eps * t) for x, t in zip(xs, ts)])
    hi, lo = (hi, lo) if isinstance(hi, tuple) else ((hi,), (lo,))
    return [(a.value - b.value) / (2 * eps) for a, b in zip(hi, lo)]


def k5(a, b, c):
    shared = vexp(a * b)
    return shared * c + vsin(c * c - a), shared - 3.0 * b, a


for xs, ts in (((0.1, 0.2, 0.3), (1.0, -2.0, 0.5)), ((-0.7, 1.1, 0.4), (0.0, 0.0, 1.0))):
    got, want = var_jvp(k5, xs, ts)[1], central5(k5, xs, ts)
    assert np.allclose(got, want, atol=1e-8), (
        f"k at {xs}, direction {ts}: expected {np.round(want, 6).tolist()} (central "
        f"differences); got {got}")
got5 = var_jvp(lambda x, y: x * 2.0, (1.0, 5.0), (0.0, 1.0))[1]
assert np.allclose(got5, (0.0,)), f"2 x in the direction of the unused y: expected (0,); got {got5}"


def long_chain(x):
    for _ in range(5000):
        x = x * 0.9999 + 0.001
    return x


got5 = var_jvp(long_chain, (1.0,), (2.0,))[1][0]
assert np.isclose(got5, 2 * 0.9999 ** 5000), \
    f"5000 steps x <- 0.9999 x + 0.001, tangent 2: expected {2 * 0.9999 ** 5000:.6f}; got {got5}"
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 1.6 — the computation graph, with the cotangent on each edge
# The tutorial's backward pass keeps one cotangent per node and forgets how it was
# assembled. Keep the pieces instead. Every edge `parent → child` is one **use** of the
# parent by the child (`x * x` uses `x` twice: two edges). The value of an edge is the
# derivative of the output with respect to that use alone: cut the edge, give the child
# an independent copy of the parent (same value) on it, and differentiate the output with
# respect to the copy. So the values on the edges that leave a node add up to the
# derivative of the output with respect to the node.
#
# Write `edge_cotangents(end)`: the list of triples `(parent, child, value)`, one per
# edge, in any order. Work out how each value follows from quantities you can compute,
# and in which order to walk the graph so that each is ready when it is needed. The tests
# include a chain of 3000 products and a graph with $2^{40}$ paths from its input to its
# output; each must take well under a second.
#
# <details><summary>Hint 1 (the idea)</summary>
#
# On the edge `p → c`, the output depends on the copy only through `c`. One link of the
# chain rule: which quantity of the child does the edge's value need, and where did the
# tutorial meet it?
# </details>
#
# <details><summary>Hint 2 (the method)</summary>
#
# That quantity of the child is known only once *every* edge leaving the child is
# known. Which order of the nodes (exercise 1.4) guarantees it? Check on the grade cell's
# $\sin(x^2) + x$ by hand: draw its five edges, and compare the sum over the edges
# leaving `x` with a central difference.
# </details>

# %% solution id=ex01_6 title="Cotangent on each edge" forbids="minimanc.autodiff.graph.computation_graph"  # noqa: E501
def edge_cotangents(end):
    ### BEGIN SOLUTION
    # the value of p -> c is d end / d c times d c / d p, and d end / d c (the child's
    # cotangent) is the sum over the edges leaving c: complete once every node that uses
    # c was visited, which the topological order (each node before its parents) gives
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
sq = x * x
s_ = vsin(sq)
y = s_ + x
edges = edge_cotangents(y)
assert len(edges) == 5, f"sin(x x) + x: 5 edges expected (x x counts twice); got {len(edges)}"


def values(parent, child, edges=edges):
    return sorted(round(float(ct), 4) for p, ch, ct in edges if p is parent and ch is child)


assert values(s_, y) == [1.0] and values(x, y) == [1.0], (
    f"sin(x x) + x at x = 0.7: expected 1.0 on each edge into the output; got "
    f"{values(s_, y)} (sin -> add) and {values(x, y)} (x -> add)")
assert values(sq, s_) == [0.8823], \
    f"the same case: expected 0.8823 on the edge x x -> sin; got {values(sq, s_)}"
assert values(x, sq) == [0.6176, 0.6176], \
    f"the same case: expected 0.6176 on each of the two edges x -> x x; got {values(x, sq)}"
x_bar = sum(ct for p, _, ct in edges if p is x)
fd = (math.sin(0.7001 ** 2) + 0.7001 - math.sin(0.6999 ** 2) - 0.6999) / 0.0002
assert abs(x_bar - fd) < 1e-6, \
    f"the same case: expected the edges leaving x to add up to {fd:.6f}; got {x_bar:.6f}"
### BEGIN HIDDEN TESTS
a, b = Var(0.4), Var(-1.2)
ab = a * b
e_b = vexp(b)
sn = vsin(ab)
prod = a * e_b
h_out = sn + prod
got = edge_cotangents(h_out)
want = [(sn, h_out, 1.0), (prod, h_out, 1.0), (a, prod, math.exp(-1.2)), (e_b, prod, 0.4),
        (b, e_b, 0.4 * math.exp(-1.2)), (ab, sn, math.cos(-0.48)),
        (a, ab, math.cos(-0.48) * -1.2), (b, ab, math.cos(-0.48) * 0.4)]
assert len(got) == len(want), f"sin(a b) + a e^b: {len(want)} edges expected, got {len(got)}"
for wp, wch, wct in want:
    found = [ct for p, ch, ct in got if p is wp and ch is wch]
    assert len(found) == 1 and abs(found[0] - wct) < 1e-12, (
        f"sin(a b) + a e^b at (0.4, -1.2): expected one edge {wp} -> {wch} carrying "
        f"{wct:.6f}; got {found}")
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
v0 = Var(0.3)                    # 40 levels v <- sin(v) + 0.5 v: 2^40 paths from v0 to the end
levels, v = [], v0
for _ in range(40):
    sin_v = vsin(v)
    levels.append((v, sin_v))
    v = sin_v + v * 0.5
ladder = edge_cotangents(v)
assert len(ladder) == 200, f"40 levels of sin(v) + 0.5 v: expected 200 edges; got {len(ladder)}"
rest = 1.0                       # d end / d (v after level k), from the last level back
for k in range(39, -1, -1):
    vk, sin_k = levels[k]
    found = [ct for p, ch, ct in ladder if p is vk and ch is sin_k]
    want_k = rest * math.cos(vk.value)
    assert len(found) == 1 and math.isclose(found[0], want_k, rel_tol=1e-9), (
        f"40 levels of sin(v) + 0.5 v from 0.3: at level {k} expected the edge v -> sin(v) "
        f"to carry {want_k:.6g}; got {found}")
    rest *= math.cos(vk.value) + 0.5
x_ladder = sum(ct for p, _, ct in ladder if p is v0)
assert math.isclose(x_ladder, rest, rel_tol=1e-9), (
    f"the same ladder: expected the edges leaving its input to add up to {rest:.6g}; got "
    f"{x_ladder:.6g}")
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
# `minimanc.autodiff.grad` does on arrays what your `edge_cotangents` does on
# scalars (each input's cotangent is the sum of the edges that leave it), with VJPs
# like the ones above (in the modules behind `minimanc/autodiff/numpy.py`). From
# here on the notebooks use the library, so they run even if an exercise above is
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
