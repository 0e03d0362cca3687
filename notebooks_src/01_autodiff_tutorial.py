# %% [markdown]
# # Chapter 1 — Automatic differentiation from scratch
#
# Modules built in this chapter: `minimanc.autodiff` (its `__init__.py`, `numpy.py`,
# `check.py`), its pytrees `minimanc.tree` and `minimanc.engine`.
#
# Every model of the MANC paper — the predicate CNN (eq. 7), the soft automaton
# (eqs. 8–9), the DMP head with learned gains (eqs. 10–11) — is trained by
# behaviour cloning (Algorithm 1): minimise the mean squared error between the
# predicted and the human controls by gradient descent. So we need the gradient
# of **one scalar loss** with respect to **many parameters**. Reverse-mode
# automatic differentiation computes all of it for the price of a few forward
# passes. In this chapter we build it from the chain rule up, in ~300 lines
# you can read in one sitting, and check it against JAX.
#
# Plan: (1) the chain rule on scalars, (2) vector-Jacobian products,
# (3) broadcasting, (4) the tape, (5) the topological sort, (6) writing a
# primitive, (7) pytrees and a tiny training loop, (8) side by side with JAX,
# (9) what the engine does not do.
#
# **Objectives.** After this chapter you can
# - derive and write vector-Jacobian products, also across broadcasting
# - build reverse-mode `grad` from a tape and its topological order
# - check any gradient against central differences
#
# **Prerequisites.** Chapter 0; NumPy broadcasting; the chain rule.
#
# **Time.** About 60 minutes for the tutorial and 120 for the exercises.

# %%
import math

import numpy as np

import minimanc.autodiff.numpy as anp
from minimanc import engine
from minimanc.autodiff import (
    TracerConversionError,
    check_grads,
    defvjp,
    grad,
    primitive,
    value_and_grad,
)

rng = np.random.default_rng(0)

# %% [markdown]
# ## 1. The chain rule on scalars
# Take $f(x) = \sin(x^2)$. Name the intermediate values: $a = x^2$, $b = \sin a$.
# The chain rule multiplies the local derivatives **from the output back**:
#
# $$\frac{df}{dx} = \underbrace{\frac{db}{da}}_{\cos a}\;\underbrace{\frac{da}{dx}}_{2x}.$$
#
# Starting from $\bar b = \partial f/\partial b = 1$ we get
# $\bar a = \bar b \cos a$ and $\bar x = \bar a \cdot 2x$. The bars are
# *cotangents*: the derivative of the final output with respect to each
# intermediate value. We check the result with a central difference
# $(f(x+\varepsilon) - f(x-\varepsilon)) / 2\varepsilon$, whose error is $O(\varepsilon^2)$.

# %%
x = 1.3
a = x * x          # forward pass, keeping the intermediate values
b = np.sin(a)
b_bar = 1.0        # backward pass: cotangents from the output back
a_bar = b_bar * np.cos(a)
x_bar = a_bar * 2 * x
eps = 1e-6
fd = (np.sin((x + eps) ** 2) - np.sin((x - eps) ** 2)) / (2 * eps)
assert abs(x_bar - fd) < 1e-8
print(f"by hand {x_bar:.6f}   central difference {fd:.6f}")

# %% [markdown]
# ## 2. From derivatives to vector-Jacobian products
# For arrays, $y = f(x)$ has a Jacobian $J = \partial y / \partial x$ (one row per
# output element, one column per input element). If a scalar loss $L$ depends
# on $y$ with cotangent $\bar y = \partial L/\partial y$, then
#
# $$\bar x = J^\top \bar y \qquad\text{(a vector-Jacobian product, VJP).}$$
#
# Reverse mode never builds $J$: each operation knows how to map $\bar y$ to
# $\bar x$ directly. For an element-wise function $J$ is diagonal, so the VJP is
# an element-wise product; for a matrix product $Y = AB$ it is
# $\bar A = \bar Y B^\top$, $\bar B = A^\top \bar Y$. Below we build the full
# Jacobian of $y = W x + e^{x}$ by finite differences and compare $J^\top \bar y$
# with the two VJP rules.

# %%
W = rng.normal(size=(3, 3))
x0 = rng.normal(size=3)
y_bar = rng.normal(size=3)


def f(x):
    return W @ x + np.exp(x)


J = np.stack([(f(x0 + eps * e) - f(x0 - eps * e)) / (2 * eps) for e in np.eye(3)], axis=1)
vjp_rules = W.T @ y_bar + np.exp(x0) * y_bar   # matmul rule + element-wise rule
assert np.allclose(J.T @ y_bar, vjp_rules, atol=1e-8)
print("Jacobian shape", J.shape, "| J^T y_bar =", np.round(J.T @ y_bar, 4))

# %% [markdown]
# The Jacobian of a realistic layer is huge — a 3×3 convolution from a
# 32×64×64×3 batch to 32×32×32×16 channels has 524,288 outputs and 393,216
# inputs — but its VJP costs about as much as the layer itself. That is why
# every primitive in `minimanc.autodiff.numpy` carries a VJP, not a Jacobian.
#
# ## 3. Broadcasting: the VJP of a copy is a sum
# `x + b` with `x` of shape (5, 3) and `b` of shape (3,) copies `b` into every row.
# A value used several times receives the **sum** of the cotangents of its
# copies, so $\bar b$ is $\bar y$ summed over the rows. `unbroadcast` does this
# for any shape: it sums over new leading axes and over axes where the input
# had size one.

# %%
from minimanc.autodiff import unbroadcast

g = np.arange(15.0).reshape(5, 3)
print(unbroadcast((3,), g), unbroadcast((5, 1), g).ravel(), unbroadcast((), g))
gb = grad(lambda b: anp.sum((np.ones((5, 3)) + b) * g))(np.zeros(3))
assert np.allclose(gb, g.sum(axis=0))

# %% [markdown]
# ## 4. The tape: boxes that remember their parents
# To run the chain rule automatically, the forward pass must record what
# happened. `grad` wraps each input in a `Box`; every function of
# `minimanc.autodiff.numpy` (`anp`) is a *primitive*: given a box it computes the
# plain NumPy result, and returns a new box that remembers the primitive, its
# arguments and its **parents** — in a tuple, so the order is fixed.
#
# The code of `primitive` is a dozen lines (open `minimanc/autodiff/primitives.py`;
# the package `minimanc.autodiff` gathers the engine's pieces, one module each); each VJP
# sits right next to its forward definition in the modules behind
# `minimanc/autodiff/numpy.py` (here `elementwise.py`), e.g.
#
# ```python
# multiply = primitive(np.multiply)
# defvjp(multiply, lambda g, ans, x, y: unbroadcast(x, g * y),
#                  lambda g, ans, x, y: unbroadcast(y, g * x))
# ```
# Let us trace $y = \sin(x \cdot x) + x$ by hand and look at the graph.

# %%
from minimanc.autodiff import Box, backward, toposort

xb = Box(np.array(0.7))
yb = anp.sin(xb * xb) + xb
for node in toposort(yb):
    parents = [f"arg{i}" for i, _ in node._parents]
    name = node._prim.__name__ if node._prim else "input"
    print(f"{name:>8}  value={float(node.value):.4f}  parents={parents}")

# %% [markdown]
# `toposort` lists every box **before its parents**: the output first, the
# input last (`multiply` has the same box as both of its parents). The backward
# pass walks this list once, calls each VJP and adds the cotangents flowing into
# each parent. `x` is used three times here (twice
# in the product, once in the sum), so its cotangent is the sum of three
# contributions: $\bar x = \cos(x^2)\,(x + x) + 1$.

# %%
leaves = backward(yb, np.array(1.0))
x_bar = leaves[id(xb)]
assert np.isclose(x_bar, np.cos(0.7**2) * 2 * 0.7 + 1)
print(f"x_bar = {float(x_bar):.6f}")

# %% [markdown]
# The backward pass above keeps one cotangent per node. To *see* how each one
# is assembled, `computation_graph(f, *args)` runs the same reverse pass but
# records the cotangent that flows along **each edge** `parent → child`: the
# VJP of the child's primitive applied to the child's cotangent. A node's
# cotangent is the sum over the edges that leave it — here the three edges
# leaving `arg0` add up to $\bar x$. (Exercise 1.6 writes this traversal.)

# %%
from minimanc.autodiff import computation_graph

graph = computation_graph(lambda x: anp.sin(x * x) + x, np.array(0.7))
print(graph)   # cotangents to 4 decimals: cos(0.49) = 0.8823, 0.7 cos(0.49) = 0.6176
from_edges = sum(float(e.cotangent) for e in graph.edges if e.parent == 0)
assert np.isclose(from_edges, float(x_bar)) and np.isclose(float(graph.gradients()[0]), x_bar)

# %% [markdown]
# Drawn, with a second function of two inputs: nodes sit in columns by depth,
# each edge carries its cotangent (red). In $h(x, y) = \sin(xy) + x e^y$ the
# input $x$ feeds two products, so $\partial h/\partial x$ is the sum of the
# two red numbers on its outgoing edges: $-1.064 + 0.301 = -0.763$.

# %%
import matplotlib.pyplot as plt

from minimanc.viz.graph import plot_graph

graph_h = computation_graph(lambda x, y: anp.sin(x * y) + x * anp.exp(y), np.array(0.4),
                            np.array(-1.2))
fig, axes = plt.subplots(1, 2, figsize=(13, 3.6), gridspec_kw={"width_ratios": [1, 1.25]})
plot_graph(graph, axes[0])
axes[0].set_title("sin(x·x) + x at x = 0.7")
plot_graph(graph_h, axes[1])
axes[1].set_title("sin(x·y) + x·exp(y) at (0.4, −1.2)")
plt.show()
dh_dx = sum(float(e.cotangent) for e in graph_h.edges if e.parent == 0)
assert np.isclose(dh_dx, np.cos(-0.48) * -1.2 + np.exp(-1.2))
print(f"dh/dx from the edges of arg0: {dh_dx:.4f}")

# %% [markdown]
# ## 5. Why a topological sort, and why an iterative one
# A box may only pass its cotangent to its parents once it has received **all**
# its own contributions, i.e. after every box that uses it. A topological order
# guarantees that. Two classic bugs of small engines:
#
# * parents kept in a `set` (micrograd): the order in which contributions are
#   added then depends on memory addresses, and floating-point sums are not
#   associative, so gradients change in the last bits from run to run. We keep
#   tuples, so gradients are bit-identical;
# * a recursive depth-first search: Python stops at ~1,000 nested calls, while
#   an unrolled recurrence (an LSTM over a long horizon, a DMP rollout of many
#   steps) easily makes chains of 10,000 operations. Our sort uses an explicit
#   stack.

# %%
import sys


def chain(x, xp):
    for _ in range(10_000):
        x = x + 1e-4 * xp.sin(x)
    return xp.sum(x)


x0 = np.array([0.1, 2.0])
print("chain longer than the recursion limit:", 10_000 > sys.getrecursionlimit())
g1 = grad(chain)(x0, anp)
g2 = grad(chain)(x0, anp)
assert g1.tobytes() == g2.tobytes()   # bit-identical, run after run
fd = [(chain(x0 + eps * e, np) - chain(x0 - eps * e, np)) / (2 * eps) for e in np.eye(2)]
assert np.allclose(g1, fd, rtol=1e-6)
print("gradient through 10,000 steps:", np.round(g1, 4), " central difference:", np.round(fd, 4))

# %% [markdown]
# ## 6. Writing a primitive, and checking it
# Any plain-NumPy function becomes differentiable with `@primitive` and one VJP
# per positional argument: `vjp(g, ans, *args)` receives the output cotangent,
# the forward result and the raw arguments. Here is softplus,
# $s(x) = \log(1 + e^x)$ with $s'(x) = \sigma(x) = 1 - e^{-s(x)}$: the VJP reuses
# `ans`. `check_grads` compares `grad` with central differences for every
# element of every argument and reports the worst errors and where they occur.

# %%
@primitive
def softplus(x):
    return np.logaddexp(0.0, x)


defvjp(softplus, lambda g, ans, x: g * -np.expm1(-ans))

report = check_grads(lambda x: anp.sum(softplus(x) ** 2), rng.normal(size=(3, 4)), verbose=False)
assert report.passed and report.max_abs_err < 1e-7
print(f"checked {report.n_checked} elements: passed={report.passed}")

# %% [markdown]
# A primitive without a VJP fails loudly, naming itself, instead of returning
# a silently wrong gradient:

# %%
@primitive
def floor_div2(x):
    return np.floor(x / 2)


try:
    grad(lambda x: anp.sum(floor_div2(x)))(np.ones(2))
except NotImplementedError as err:
    print(err)

# %% [markdown]
# ## 7. Pytrees and a tiny training loop
# Parameters are nested dicts, lists and tuples of arrays (*pytrees*); `grad`
# returns a gradient of the same structure, like `jax.grad`. `argnums` picks
# the arguments to differentiate; `value_and_grad` returns the loss too. We fit
# a two-layer network to $y = \sin(3x)$ with plain gradient descent. (300 steps of
# training: the printed losses depend on the CPU's summation order, so the cell is
# checked by its assert, not by its digits.)

# %% tags=["nbval-ignore-output"]
def mlp(params, x, xp):
    h = xp.tanh(x @ params["hidden"]["w"] + params["hidden"]["b"])
    return h @ params["out"]["w"] + params["out"]["b"]


def loss(params, x, y, xp):
    return xp.mean((mlp(params, x, xp) - y) ** 2)


x_train = np.linspace(-1, 1, 64)[:, None]
y_train = np.sin(3 * x_train)
params = {"hidden": {"w": rng.normal(size=(1, 16)), "b": np.zeros(16)},
          "out": {"w": rng.normal(size=(16, 1)) * 0.1, "b": np.zeros(1)}}
step = value_and_grad(loss)
for it in range(301):
    value, grads = step(params, x_train, y_train, anp)
    params = {layer: {k: params[layer][k] - 0.2 * grads[layer][k] for k in params[layer]}
              for layer in params}
    if it % 100 == 0:
        print(f"step {it:3d}  loss {float(value):.4f}")
assert float(value) < 0.02

# %% [markdown]
# ## 8. Side by side with JAX
# The model above takes the array namespace `xp` as an argument: with
# `anp` it runs on our engine, with `jax.numpy` on JAX. `minimanc.engine(name)`
# bundles the namespace, `grad`, `value_and_grad`, `jit` and neural-net
# primitives, so one copy of each model serves both. `engine("jax")` turns on
# float64, and the two engines agree to rounding error (on the trained network,
# so the printed loss is checked by the assert, not by its digits).

# %% tags=["nbval-ignore-output"]
results = {}
for name in ("numpy", "jax"):
    eng = engine(name)
    val, g = eng.value_and_grad(loss)(params, x_train, y_train, eng.xp)
    results[name] = (float(val), np.asarray(g["hidden"]["w"]))
diff = np.max(np.abs(results["numpy"][1] - results["jax"][1]))
assert abs(results["numpy"][0] - results["jax"][0]) < 1e-12 and diff < 1e-10
print(f"loss numpy {results['numpy'][0]:.6f}  jax {results['jax'][0]:.6f}  "
      f"max gradient difference < 1e-10: {diff < 1e-10}")

# %% [markdown]
# What JAX adds is `jit`: it traces the function once and compiles it with XLA,
# so the Python overhead of our tape disappears; `engine("numpy").jit` is the
# identity. Chapter 2 times both engines on a small CNN.
#
# ## 9. What the engine does not do
# * **No higher-order derivatives**: VJPs are plain NumPy, so `grad(grad(f))`
#   raises a clear error (use the `jax` engine).
# * **No in-place updates** of traced arrays (`x[0] = 1`, `.at[]`): write model
#   code functionally (also a JAX requirement).
# * **float32 stays float32**: gradients keep the dtype of the inputs; integer
#   inputs are refused, as in JAX.
# * **A gradient is never dropped silently**: `float(x)`, `x.item()`,
#   `math.sin(x)`, `np.asarray(x)` or `y[i] = x` on a traced value raise
#   `TracerConversionError`, saying what to write instead; `stop_gradient(x)`
#   drops the gradient on purpose. NumPy's own `np.sum`, `np.exp`, … dispatch
#   to `minimanc.autodiff.numpy`; those without a derivative say so.

# %%
try:
    grad(lambda x: grad(lambda y: y * y)(x))(1.0)
except NotImplementedError as err:
    print(err)
try:
    grad(lambda x: anp.sum(x * 1.0))(np.arange(3))
except TypeError as err:
    print(err)
try:
    grad(lambda x: math.sin(x) * 2)(1.0)
except TracerConversionError as err:
    print(err)
print(grad(lambda x: np.sum(np.exp(x)))(np.zeros(2)))  # NumPy's own sum and exp: traced
w32 = rng.normal(size=(3, 2)).astype(np.float32)
print(grad(lambda w: anp.sum(anp.tanh(w) ** 2))(w32).dtype)

# %% [markdown]
# ## Paper vs. this course
# Chapter 1 is infrastructure: the paper (`manc.tex`) never says how its
# gradients are computed. Where this course departs from it, and where the
# paper slips:
#
# * **A framework vs. an engine we write.** The authors trained in a
#   deep-learning framework (their model code was never released); we build
#   reverse mode from scratch, first-order only, and check it against JAX
#   (section 8). Every model of chapters 2–10 is trained with it or with
#   `engine("jax")` — the same code on both.
# * **float64 by default.** Our engine computes in the dtype of its inputs
#   (NumPy's default float64); frameworks default to float32. `minimanc.train`
#   trains in float32 on JAX by default, for speed.
# * **Algorithm 1's step divides by $m$ twice.** Line 10 writes
#   $\theta \leftarrow \theta - \gamma \frac1m \nabla L$ with $L = \mathrm{MSE}$,
#   which is already a mean over the minibatch of $m$ samples; read literally,
#   the gradient is averaged twice (or $L$ is meant as a sum). We use the mean
#   loss and no extra $\frac1m$: the same step with $\gamma$ rescaled by $m$.
# * **Long chains.** Algorithm 1 differentiates through a single DMP step per
#   sample; the DMP windows of `minimanc.train` span whole scenes (40 steps,
#   chapter 9), i.e. chains of thousands of operations. That is why our
#   topological sort is iterative (section 5): a recursive one would stop at
#   Python's recursion limit.
