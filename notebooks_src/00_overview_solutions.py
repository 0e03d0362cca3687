# %% [markdown]
# # Chapter 0 — Warm-up exercises
#
# Three small tools that later chapters build into the library: points into
# the ego frame (chapter 7, `minimanc.world`), a column softmax (chapter 5,
# `minimanc.vagn`) and one explicit Euler step (chapter 3, `minimanc.dmp`).
# Those chapters build the library's versions; this chapter builds the course
# machinery these exercises run on: `minimanc.exercises` (solutions →
# exercises, grading) and the `minimanc` command (`minimanc.cli`).
# Replace each `raise NotImplementedError(...)` with your code, then run the
# grade cell below it; `minimanc grade exercises/00_overview.ipynb` scores
# the whole notebook.

# %%
import numpy as np

rng = np.random.default_rng(0)

# %% [markdown]
# ## Exercise 0.1 — points into the ego frame
# The ego vehicle sits at position $(x_e, y_e)$ with heading $\psi$ (radians,
# counter-clockwise from the world $x$ axis). Express world points in the ego
# frame: $x$ forward, $y$ to the left,
# $p_{ego} = R(-\psi)\,(p - (x_e, y_e))$.
# `points` has shape `(n, 2)`, `ego` is `(x_e, y_e, psi)`.

# %% solution id=ex00_1 title="Points into the ego frame" forbids="minimanc.world.geometry.to_ego_frame"  # noqa: E501
def to_ego_frame(points, ego):
    ### BEGIN SOLUTION
    x, y, psi = ego
    c, s = np.cos(psi), np.sin(psi)
    d = np.asarray(points, dtype=float) - np.array([x, y])
    return np.stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]], axis=1)
    ### END SOLUTION

# %% grade id=ex00_1_tests points=2
ego = (10.0, 5.0, np.pi / 2)          # facing world +y
ahead = to_ego_frame(np.array([[10.0, 15.0]]), ego)
assert np.allclose(ahead, [[10.0, 0.0]]), f"10 m straight ahead: expected [[10, 0]]; got {ahead}"
left = to_ego_frame(np.array([[0.0, 5.0]]), ego)
assert np.allclose(left, [[0.0, 10.0]]), f"10 m to the left: expected [[0, 10]]; got {left}"
### BEGIN HIDDEN TESTS
pts = rng.normal(size=(20, 2)) * 30
e = (1.5, -2.0, 0.7)
back = to_ego_frame(pts, e)
assert np.allclose(np.linalg.norm(back, axis=1), np.linalg.norm(pts - [1.5, -2.0], axis=1)), \
    "a rotation keeps each point's distance to the ego"
assert np.allclose(to_ego_frame(pts, (0.0, 0.0, 0.0)), pts), \
    "an ego at the origin facing +x: the points are unchanged"
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 0.2 — a column softmax
# The vAGN (chapter 5) turns a matrix of scores into a transition matrix whose
# **columns** sum to one: $T_{ij} = e^{A_{ij}} / \sum_k e^{A_{kj}}$. Subtract
# each column's maximum first so that large scores do not overflow.

# %% solution id=ex00_2 title="Column softmax"
def column_softmax(a):
    ### BEGIN SOLUTION
    a = np.asarray(a, dtype=float)
    e = np.exp(a - a.max(axis=0, keepdims=True))
    return e / e.sum(axis=0, keepdims=True)
    ### END SOLUTION

# %% grade id=ex00_2_tests points=2
t = column_softmax(np.array([[0.0, 1.0], [0.0, 3.0]]))
assert np.allclose(t.sum(axis=0), 1.0), f"every column must sum to one; got {t.sum(axis=0)}"
assert np.allclose(t[:, 0], [0.5, 0.5]), f"equal scores: expected [0.5, 0.5]; got {t[:, 0]}"
assert np.isclose(t[1, 1], np.exp(3) / (np.exp(1) + np.exp(3))), \
    f"expected e^3 / (e^1 + e^3) = {np.exp(3) / (np.exp(1) + np.exp(3)):.6f}; got {t[1, 1]}"
### BEGIN HIDDEN TESTS
big = column_softmax(np.array([[1000.0, 0.0], [999.0, 0.0]]))
assert np.all(np.isfinite(big)) and np.allclose(big.sum(axis=0), 1.0), \
    "scores of 1000 must not overflow: subtract each column's maximum"
r = column_softmax(rng.normal(size=(5, 5)))
assert np.all(r > 0) and np.allclose(r.sum(axis=0), 1.0), \
    "expected positive entries and columns (not rows) summing to one"
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 0.3 — one explicit Euler step
# For $\dot{s} = f(s)$, explicit Euler advances the state by
# $s_{t+\Delta t} = s_t + \Delta t\, f(s_t)$. Chapter 3 uses it for DMPs.

# %% solution id=ex00_3 title="Explicit Euler step"
def euler_step(f, s, dt):
    ### BEGIN SOLUTION
    return s + dt * f(s)
    ### END SOLUTION

# %% grade id=ex00_3_tests points=1
decay = lambda s: -s  # noqa: E731
assert np.isclose(euler_step(decay, 1.0, 0.1), 0.9), "1 + 0.1 * (-1) = 0.9"
### BEGIN HIDDEN TESTS
s = np.array([1.0, 2.0])
assert np.allclose(euler_step(lambda v: np.array([v[1], -v[0]]), s, 0.5), [2.0, 1.5]), \
    "(1, 2) + 0.5 * (2, -1) = (2, 1.5)"
### END HIDDEN TESTS

# %% [markdown]
# ## Using the three tools together
# From here on, the notebook uses the library's versions, so it runs even while
# your exercises are unfinished: a car at the origin facing +y sees a point at
# world (0, 10) straight ahead.

# %%
c, s = np.cos(np.pi / 2), np.sin(np.pi / 2)
d = np.array([0.0, 10.0])
print(np.round([c * d[0] + s * d[1], -s * d[0] + c * d[1]], 3))
