# %% [markdown]
# # Chapter 0 — Warm-up exercises
#
# Three small tasks on tools that later chapters build into the library: points
# into the ego frame (chapter 7, `minimanc.world`), the scores behind a column
# softmax (chapter 5, `minimanc.vagn`) and the explicit Euler step (chapter 3,
# `minimanc.dmp`). Each asks for a little derivation, not a formula to copy.
# Those chapters build the library's versions; this chapter builds the course
# machinery these exercises run on: `minimanc.exercises` (solutions →
# exercises, grading) and the `minimanc` command (`minimanc.cli`).
# Replace each `raise NotImplementedError(...)` with your code, then run the
# grade cell below it; `minimanc grade exercises/00_overview.ipynb` scores
# the whole notebook.

# %%
import math

import numpy as np

rng = np.random.default_rng(0)

# %% [markdown]
# ## Exercise 0.1 — points into the ego frame
# The ego vehicle sits at position $(x_e, y_e)$ with heading $\psi$ (radians,
# counter-clockwise from the world $x$ axis). Write `to_ego_frame(points, ego)`:
# the world points `points`, shape `(n, 2)`, in the ego frame — origin at the
# ego, $x$ forward along its heading, $y$ to its left. `ego` is
# `(x_e, y_e, psi)`. Work out the rotation yourself: which way, and by how much,
# must the offsets turn?
#
# <details><summary>Hint 1 (the idea)</summary>
#
# A point straight ahead of the ego must land on the positive $x$ axis, a point
# to its left on the positive $y$ axis. Try $\psi = 90°$ on paper first.
# </details>
#
# <details><summary>Hint 2 (the method)</summary>
#
# Subtract the ego position, then rotate the offset by the angle that takes the
# heading direction $(\cos\psi, \sin\psi)$ onto $(1, 0)$. Check both test points
# of the grade cell by hand.
# </details>

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
assert np.allclose(ahead, [[10.0, 0.0]]), \
    f"ego at (10, 5) facing +y, world point (10, 15): expected [[10, 0]]; got {ahead}"
left = to_ego_frame(np.array([[0.0, 5.0]]), ego)
assert np.allclose(left, [[0.0, 10.0]]), \
    f"ego at (10, 5) facing +y, world point (0, 5): expected [[0, 10]]; got {left}"
### BEGIN HIDDEN TESTS
test_rng = np.random.default_rng(10)  # the tests' own draws, not the notebook's rng
pts = test_rng.normal(size=(20, 2)) * 30
e = (1.5, -2.0, 0.7)
back = to_ego_frame(pts, e)
assert np.allclose(np.linalg.norm(back, axis=1), np.linalg.norm(pts - [1.5, -2.0], axis=1)), \
    "ego at (1.5, -2), heading 0.7: expected each point's distance to the ego kept"
assert np.allclose(to_ego_frame(pts, (0.0, 0.0, 0.0)), pts), \
    "an ego at the origin facing +x: expected the points unchanged"
behind = to_ego_frame(np.array([[1.5 - 4 * np.cos(0.7), -2.0 - 4 * np.sin(0.7)]]), e)
assert np.allclose(behind, [[-4.0, 0.0]]), \
    f"ego at (1.5, -2), heading 0.7, a point 4 m behind it: expected [[-4, 0]]; got {behind}"
right = to_ego_frame(np.array([[1.5 + 3 * np.sin(0.7), -2.0 - 3 * np.cos(0.7)]]), e)
assert np.allclose(right, [[0.0, -3.0]]), \
    f"ego at (1.5, -2), heading 0.7, a point 3 m to its right: expected [[0, -3]]; got {right}"
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 0.2 — scores for a transition matrix
# The vAGN (chapter 5) turns a matrix of scores $A$ into a transition matrix whose
# **columns** sum to one, the column softmax $T_{ij} = e^{A_{ij}} / \sum_k e^{A_{kj}}$.
# Go the other way: write `scores_for(T)` that returns scores $A$ whose column
# softmax is `T` and whose every **column sums to zero**. `T` is square, its
# entries positive, its columns summing to one.
#
# <details><summary>Hint 1 (the idea)</summary>
#
# Add the same number to every score of one column: what happens to that column of
# $T$? So many $A$ give the same $T$; the zero-sum condition picks one.
# </details>
#
# <details><summary>Hint 2 (the method)</summary>
#
# Take the logarithm of $T_{ij}$: it is $A_{ij}$ minus something that depends on
# the column only. Then choose that column's constant so the column sums to zero.
# </details>

# %% solution id=ex00_2 title="Scores for a transition matrix"
def scores_for(T):
    ### BEGIN SOLUTION
    logt = np.log(np.asarray(T, dtype=float))
    return logt - logt.mean(axis=0, keepdims=True)
    ### END SOLUTION

# %% grade id=ex00_2_tests points=2
a2 = scores_for(np.array([[0.5, 0.8807970779778823], [0.5, 0.1192029220221177]]))
assert np.shape(a2) == (2, 2), f"a 2 x 2 T: expected scores of shape (2, 2); got {np.shape(a2)}"
assert np.allclose(a2, [[0.0, 1.0], [0.0, -1.0]]), (
    f"T = [[0.5, 0.8808], [0.5, 0.1192]]: expected A = [[0, 1], [0, -1]]; "
    f"got {np.round(a2, 4).tolist()}")
### BEGIN HIDDEN TESTS
test_rng = np.random.default_rng(20)  # the tests' own draws, not the notebook's rng
for n in (3, 5):
    e = np.exp(test_rng.normal(size=(n, n)) * 3)
    t = e / e.sum(axis=0)
    a = np.asarray(scores_for(t))
    back = np.exp(a) / np.exp(a).sum(axis=0)   # the column softmax, written out
    assert np.allclose(back, t), \
        f"a random {n} x {n} T: expected the column softmax of your scores to be T"
    assert np.allclose(a.sum(axis=0), 0.0), \
        f"a random {n} x {n} T: expected columns summing to 0; got {np.round(a.sum(0), 4)}"
u = np.asarray(scores_for(np.full((4, 4), 0.25)))
assert np.allclose(u, 0.0), f"a uniform 4 x 4 T: expected all scores 0; got {u}"
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 0.3 — how many Euler steps to halve?
# For $\dot{s} = -k s$ with $k > 0$, explicit Euler advances the state by
# $s_{n+1} = s_n + \Delta t\, f(s_n)$ (chapter 3 uses it for DMPs). Write
# `halving_steps(k, dt)`: the number of steps $n \ge 1$ after which
# $|s_n| \le |s_0| / 2$ for the first time, or `None` if that never happens.
# Some cases need thousands of steps and some never halve: derive the answer,
# do not guess a cap for a loop.
#
# <details><summary>Hint (the idea)</summary>
#
# Each step multiplies $s$ by the same number. When does its size stay at 1 or
# above, and how many factors below 1 does it take to reach ½?
# </details>

# %% solution id=ex00_3 title="Explicit Euler: steps to halve"
def halving_steps(k, dt):
    ### BEGIN SOLUTION
    r = abs(1.0 - k * dt)
    if r >= 1.0:
        return None
    if r <= 0.5:
        return 1
    return math.ceil(math.log(0.5) / math.log(r))
    ### END SOLUTION

# %% grade id=ex00_3_tests points=1
n3 = halving_steps(1.0, 0.1)
assert n3 == 7, f"k = 1, dt = 0.1: expected 7 steps; got {n3!r}"
n3 = halving_steps(1.0, 2.5)
assert n3 is None, f"k = 1, dt = 2.5: expected None; got {n3!r}"
### BEGIN HIDDEN TESTS
for k, dt, want in ((3.0, 0.5, 1), (1.0, 2.0, None), (1.0, 1.0, 1), (2.0, 0.9, 4),
                    (1.0, 1e-4, 6932), (0.5, 0.01, 139)):
    got = halving_steps(k, dt)
    assert got == want, f"k = {k}, dt = {dt}: expected {want!r}; got {got!r}"
test_rng = np.random.default_rng(30)  # the tests' own draws, not the notebook's rng
for k, dt in zip(test_rng.uniform(0.1, 5, 20), test_rng.uniform(0.01, 0.5, 20)):
    s, n = 1.0, 0                     # the steps, counted one by one
    while abs(s) > 0.5:
        s, n = s - dt * k * s, n + 1
    got = halving_steps(k, dt)
    assert got == n, f"k = {k:.4f}, dt = {dt:.4f}: expected {n} steps; got {got!r}"
### END HIDDEN TESTS

# %% [markdown]
# ## Using the three tools together
# From here on, the notebook uses the library's versions, so it runs even while
# your exercises are unfinished: a car at (10, 5) facing +y sees the world point
# (10, 15) 10 m straight ahead (`minimanc.world.geometry.to_ego_frame`, chapter 7),
# and the column softmax of the vAGN (`minimanc.vagn.transition_matrix`, chapter 5)
# turns zero scores into uniform columns.

# %%
from minimanc import vagn
from minimanc.world.geometry import to_ego_frame as library_to_ego_frame

print(np.round(library_to_ego_frame(np.array([[10.0, 15.0]]), np.array([10.0, 5.0, np.pi / 2])), 3)
      + 0.0)
print(vagn.transition_matrix(np.ones(1), np.zeros((1, 3, 3))).round(4))
