# %% [markdown]
# # Chapter 4 — Graded exercises: quaternion matrices, logged orientations, body rates
#
# Module built in this chapter: **`minimanc.quaternion`**. Read the tutorial
# `tutorials/04_quaternions.ipynb` first. Replace each
# `raise NotImplementedError(...)` with your code and run the grade cell
# below it; `minimanc grade exercises/04_quaternions.ipynb` scores the notebook.
#
# Quaternions are NumPy arrays `(..., 4)` in the order (w, x, y, z); your
# functions must work on a single quaternion and on batches (use `q[..., 0]`,
# `q[..., 1:]` and `np.stack(..., axis=-1)`).

# %%
import math

import matplotlib.pyplot as plt
import numpy as np

from minimanc import dmp
from minimanc import quaternion as Q
from minimanc.viz import exercises as vx

rng = np.random.default_rng(0)
ID = np.array([1.0, 0.0, 0.0, 0.0])


def random_unit(n, gen=None):
    """n random unit quaternions, drawn from ``gen`` (default: the notebook's rng)."""
    q = (rng if gen is None else gen).normal(size=(n, 4))
    return q / np.linalg.norm(q, axis=-1, keepdims=True)

# %% [markdown]
# ## Exercise 4.1 — the product as a matrix
# The product of eq. (3) is linear in each factor: for a fixed $p$, $q \mapsto p * q$
# is a 4×4 matrix $L(p)$, and for a fixed $q$, $p \mapsto p * q$ is another, $R(q)$:
#
# $$p * q = L(p)\, q = R(q)\, p .$$
#
# Derive both from eq. 3 and write `left_matrix(p)` and `right_matrix(q)`: arrays
# `(..., 4, 4)` for quaternions `(..., 4)` in the order (w, x, y, z). `Q.multiply` is
# switched off while this exercise is graded.
#
# <details><summary>Hint 1 (the idea)</summary>
#
# Column $j$ of $L(p)$ is $p * e_j$ for the basis quaternions $1, i, j, k$; the same
# for $R(q)$ with $e_j * q$.
# </details>
#
# <details><summary>Hint 2 (the method)</summary>
#
# Expand eq. 3 into its four components and read off the coefficient of each
# component of $q$ (or of $p$). The two matrices differ only where the cross product
# enters: its sign flips.
# </details>

# %% solution id=ex04_1 title="The product as a matrix" forbids="minimanc.quaternion.multiply"
def left_matrix(p):
    ### BEGIN SOLUTION
    w, x, y, z = np.moveaxis(np.asarray(p, dtype=float), -1, 0)
    return np.stack([np.stack([w, -x, -y, -z], -1), np.stack([x, w, -z, y], -1),
                     np.stack([y, z, w, -x], -1), np.stack([z, -y, x, w], -1)], -2)
    ### END SOLUTION


def right_matrix(q):
    ### BEGIN SOLUTION
    w, x, y, z = np.moveaxis(np.asarray(q, dtype=float), -1, 0)
    return np.stack([np.stack([w, -x, -y, -z], -1), np.stack([x, w, z, -y], -1),
                     np.stack([y, -z, w, x], -1), np.stack([z, y, -x, w], -1)], -2)
    ### END SOLUTION

# %% grade id=ex04_1_tests points=2
i, j, k = np.eye(4)[1:]
got = np.asarray(left_matrix(i)) @ j
assert np.allclose(got, k), f"L(i) j = i * j: expected k = [0, 0, 0, 1]; got {got}"
got = np.asarray(right_matrix(i)) @ j
assert np.allclose(got, -k), f"R(i) j = j * i: expected -k = [0, 0, 0, -1]; got {got}"
got = np.asarray(left_matrix(ID))
assert np.allclose(got, np.eye(4)), f"L(1): expected the 4 x 4 identity; got {got.tolist()}"
got = np.asarray(right_matrix([0.5, 0.5, 0.5, 0.5])) @ ID
assert np.allclose(got, [0.5, 0.5, 0.5, 0.5]), \
    f"R(q) 1 = 1 * q for q = (0.5, 0.5, 0.5, 0.5): expected q; got {got}"
### BEGIN HIDDEN TESTS
test_rng = np.random.default_rng(410)  # the tests' own draws, not the notebook's rng
p, q = random_unit(50, test_rng), random_unit(50, test_rng)
pw, pu, qw, qu = p[:, :1], p[:, 1:], q[:, :1], q[:, 1:]   # eq. 3, written out
want = np.concatenate([pw * qw - np.sum(pu * qu, -1, keepdims=True),
                       pw * qu + qw * pu + np.cross(pu, qu)], -1)
for name, got in (("L(p) q", np.einsum("nij,nj->ni", np.asarray(left_matrix(p)), q)),
                  ("R(q) p", np.einsum("nij,nj->ni", np.asarray(right_matrix(q)), p))):
    assert np.allclose(got, want), (
        f"a batch of 50 random unit p, q: expected {name} = p * q, e.g. sample 0: "
        f"{np.round(want[0], 4)}; got {np.round(got[0], 4)}")
shape = np.shape(left_matrix(p.reshape(5, 10, 4)))
assert shape == (5, 10, 4, 4), f"a (5, 10, 4) batch: expected shape (5, 10, 4, 4); got {shape}"
L = np.asarray(left_matrix(p))
assert np.allclose(np.einsum("nji,njk->nik", L, L), np.eye(4)), \
    "unit p: expected L(p) orthogonal (|p * q| = |q|)"
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 4.2 — the rotation matrix of a quaternion
# A unit quaternion rotates a vector $v$ by the sandwich $q\,(0, v)\,\bar q$
# (tutorial section 1), and `Q.to_matrix` turns $q$ into the 3×3 rotation matrix that
# does the same. Derive that matrix and write `to_matrix(q)`: `(..., 3, 3)` for unit
# quaternions `(..., 4)`. `Q.to_matrix` and `Q.rotate` are switched off while this
# exercise is graded.
#
# <details><summary>Hint 1 (the idea)</summary>
#
# The sandwich is two products: with the matrices of 4.1 it is one 4×4 matrix acting
# on $(0, v)$. What does it do to the first component, and which block is the 3×3
# rotation?
# </details>
#
# <details><summary>Hint 2 (the method)</summary>
#
# Each of the two products is one of 4.1's matrices, but which one (left or right
# multiplication) and of which quaternion? Work it out, then read off the block that maps
# $v$ to $v'$. Check your matrix before grading: it must be orthogonal with determinant
# +1, the same for $q$ and $-q$, and a yaw of 90° must turn $(1, 0, 0)$ into $(0, 1, 0)$.
# </details>

# %% solution id=ex04_2 title="The rotation matrix of a quaternion" forbids="minimanc.quaternion.to_matrix,minimanc.quaternion.rotate"  # noqa: E501
def to_matrix(q):
    ### BEGIN SOLUTION
    q = np.asarray(q, dtype=float)
    conj = q * np.array([1.0, -1.0, -1.0, -1.0])
    return (left_matrix(q) @ right_matrix(conj))[..., 1:, 1:]
    ### END SOLUTION

# %% grade id=ex04_2_tests points=3
got = np.asarray(to_matrix(Q.from_axis_angle(np.array([0.0, 0.0, 1.0]), np.pi / 2)))
assert np.allclose(got, [[0, -1, 0], [1, 0, 0], [0, 0, 1]]), \
    f"90 deg about z: expected [[0, -1, 0], [1, 0, 0], [0, 0, 1]]; got {np.round(got, 4).tolist()}"
got = np.asarray(to_matrix([0.5, 0.5, 0.5, 0.5]))
assert np.allclose(got @ [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]), (
    f"q = (0.5, 0.5, 0.5, 0.5), 120 deg about (1, 1, 1): expected it to take x to y; got "
    f"{np.round(got @ [1.0, 0.0, 0.0], 4)}")
### BEGIN HIDDEN TESTS
test_rng = np.random.default_rng(420)  # the tests' own draws, not the notebook's rng
qs, vs = random_unit(100, test_rng), test_rng.normal(size=(100, 3))
R = np.asarray(to_matrix(qs))
assert R.shape == (100, 3, 3), f"a batch of 100: expected shape (100, 3, 3); got {R.shape}"
sandwich = Q.multiply(Q.multiply(qs, np.concatenate([np.zeros((100, 1)), vs], -1)),
                      qs * np.array([1.0, -1.0, -1.0, -1.0]))[:, 1:]
got = np.einsum("nij,nj->ni", R, vs)
bad = int(np.argmax(np.abs(got - sandwich).max(axis=-1)))
assert np.allclose(got, sandwich), (
    f"100 random q, v: expected R(q) v = q (0, v) q*, e.g. {np.round(sandwich[bad], 4)}; "
    f"got {np.round(got[bad], 4)}")
assert np.allclose(np.asarray(to_matrix(-qs)), R), "q and -q are one rotation: expected one matrix"
assert np.allclose(np.linalg.det(R), 1.0), "expected rotations: determinant 1"
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 4.3 — the quaternion of a rotation matrix
# Logged data often stores orientations as rotation matrices. Go back: write
# `from_matrix(R)` returning the unit quaternion `(..., 4)` with $w \ge 0$ whose
# rotation matrix is `R` `(..., 3, 3)`. It must be accurate for **every** rotation,
# including rotations by π (a U-turn), where $w = 0$.
#
# <details><summary>Hint 1 (the idea)</summary>
#
# From your 4.2: the trace of the matrix gives $w^2$; the diagonal entries give
# $x^2, y^2, z^2$; sums and differences of opposite off-diagonal entries give the
# products $wx, xy, \dots$.
# </details>
#
# <details><summary>Hint 2 (the method)</summary>
#
# Dividing by a component close to 0 loses everything. Take the square root of the
# **largest** of $w^2, x^2, y^2, z^2$, and get the other three from the products with
# it; then fix the overall sign so that $w \ge 0$.
# </details>

# %% solution id=ex04_3 title="The quaternion of a rotation matrix"
def from_matrix(R):
    ### BEGIN SOLUTION
    R = np.asarray(R, dtype=float)
    t = np.trace(R, axis1=-2, axis2=-1)
    d0, d1, d2 = R[..., 0, 0], R[..., 1, 1], R[..., 2, 2]
    squares = np.stack([1 + t, 1 + d0 - d1 - d2, 1 - d0 + d1 - d2, 1 - d0 - d1 + d2], -1) / 4
    wx, wy, wz = ((R[..., 2, 1] - R[..., 1, 2]) / 4, (R[..., 0, 2] - R[..., 2, 0]) / 4,
                  (R[..., 1, 0] - R[..., 0, 1]) / 4)
    xy, xz, yz = ((R[..., 0, 1] + R[..., 1, 0]) / 4, (R[..., 0, 2] + R[..., 2, 0]) / 4,
                  (R[..., 1, 2] + R[..., 2, 1]) / 4)
    products = np.stack([np.stack([squares[..., 0], wx, wy, wz], -1),   # row a: q_a * q
                         np.stack([wx, squares[..., 1], xy, xz], -1),
                         np.stack([wy, xy, squares[..., 2], yz], -1),
                         np.stack([wz, xz, yz, squares[..., 3]], -1)], -2)
    big = np.argmax(squares, axis=-1)
    row = np.take_along_axis(products, big[..., None, None], axis=-2)[..., 0, :]
    q = row / np.sqrt(np.take_along_axis(squares, big[..., None], axis=-1))
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    return np.where(q[..., :1] < 0, -q, q)
    ### END SOLUTION

# %% grade id=ex04_3_tests points=3
got = np.asarray(from_matrix(np.eye(3)))
assert np.allclose(got, ID), f"the identity matrix: expected (1, 0, 0, 0); got {got}"
got = np.asarray(from_matrix(np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])))
assert np.allclose(got, [np.sqrt(0.5), 0.0, 0.0, np.sqrt(0.5)]), \
    f"90 deg about z: expected (0.7071, 0, 0, 0.7071); got {np.round(got, 4)}"
got = np.asarray(from_matrix(np.diag([1.0, -1.0, -1.0])))
assert np.allclose(np.abs(got), [0.0, 1.0, 0.0, 0.0]), \
    f"180 deg about x, diag(1, -1, -1): expected (0, ±1, 0, 0); got {np.round(got, 4)}"
### BEGIN HIDDEN TESTS
test_rng = np.random.default_rng(430)  # the tests' own draws, not the notebook's rng
axes = test_rng.normal(size=(60, 3))
axes /= np.linalg.norm(axes, axis=-1, keepdims=True)
angles = np.concatenate([test_rng.uniform(0, np.pi, 40), np.full(10, np.pi),
                         np.pi - 10.0 ** -test_rng.uniform(3, 9, 10)])
qs = Q.from_axis_angle(axes, angles)
qs = np.where(qs[:, :1] < 0, -qs, qs)
R = Q.to_matrix(qs)
got = np.asarray(from_matrix(R))
assert got.shape == (60, 4), f"a batch of 60: expected shape (60, 4); got {got.shape}"
back = Q.to_matrix(got / np.linalg.norm(got, axis=-1, keepdims=True))
worst = int(np.argmax(np.abs(back - R).max(axis=(1, 2))))
assert np.allclose(back, R, atol=1e-9), (
    f"rotation by {angles[worst]:.9f} rad about {np.round(axes[worst], 3)}: expected a "
    f"quaternion with this matrix; yours gives a matrix off by "
    f"{np.abs(back - R).max(axis=(1, 2))[worst]:.2e}")
assert np.allclose(np.linalg.norm(got, axis=-1), 1.0, atol=1e-12), "expected unit quaternions"
assert np.all(got[:, 0] >= 0), "expected w >= 0"
assert np.allclose(got[:40], qs[:40], atol=1e-9), "angles below pi: expected the w >= 0 quaternion"
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 4.4 — angular velocities from a log with an irregular clock
# Eq. 5 turns an angular velocity into the next orientation,
# $q_{k+1} = \exp(\tfrac{\Delta t}{2}\,\eta_k) * q_k$ (world frame, τ = 1), and tutorial
# section 3 takes the rotation from one orientation to the next. A data set goes the other
# way: it logs orientations, and the controls (a yaw rate that changes all the time) must
# be recovered from them. This log's clock is irregular: sample $k$ is taken at
# `times[k]`, and the gaps differ. Write `angular_velocities(qs, times)`: for `qs` of
# shape `(K + 1, 4)` and increasing `times` of shape `(K + 1,)`, return the world-frame
# angular velocity **at each interior sample time** $t_1, \dots, t_{K-1}$, shape
# `(K - 1, 3)`, with an error that falls as the **square** of the gaps (halve every gap:
# a quarter of the error). Between two samples the orientation turns **the short way
# round** (at most π), and the log may store any sample as $q$ or $-q$.
# `Q.orientation_error` is switched off while this exercise is graded.
#
# <details><summary>Hint 1 (the idea)</summary>
#
# The constant angular velocity that takes $q_k$ to $q_{k+1}$ is the *average* rate over
# that gap. At which instant of the gap is an average rate most accurate? You have one
# such estimate on each side of $t_k$, at different distances from it.
# </details>
#
# <details><summary>Hint 2 (the method)</summary>
#
# Combine the two estimates around $t_k$ so that the result is exact whenever the rate
# changes linearly in time. Check it on a yaw $\psi(t) = 0.3\,t^2$ sampled at
# $t = 0, 0.1, 0.4$ (the grade cell's first case): the rate at $t = 0.1$ is $0.06$, and
# the plain mean of the two estimates is not. Then halve the gaps of a curved 3-D path
# and watch the error.
# </details>

# %% solution id=ex04_4 title="Angular velocities from an irregular log" forbids="minimanc.quaternion.orientation_error"  # noqa: E501
def angular_velocities(qs, times):
    ### BEGIN SOLUTION
    qs, times = np.asarray(qs, dtype=float), np.asarray(times, dtype=float)
    r = Q.multiply(qs[1:], Q.conjugate(qs[:-1]))
    r = np.where(r[..., :1] < 0, -r, r)                  # the short way round
    gaps = np.diff(times)[:, None]
    mid = 2.0 * Q.log(r) / gaps                          # the rate at each gap's midpoint
    before, after = gaps[:-1], gaps[1:]
    # linear interpolation between the midpoints t_k - before / 2 and t_k + after / 2
    return (after * mid[:-1] + before * mid[1:]) / (before + after)
    ### END SOLUTION

# %% grade id=ex04_4_tests points=4
got = np.asarray(angular_velocities(Q.from_yaw(0.3 * np.array([0.0, 0.1, 0.4]) ** 2),
                                    [0.0, 0.1, 0.4]))
assert np.shape(got) == (1, 3), f"three orientations: expected shape (1, 3); got {np.shape(got)}"
assert np.allclose(got, [[0.0, 0.0, 0.06]], atol=1e-9), (
    f"yaw 0.3 t^2 logged at t = 0, 0.1, 0.4: expected the rate at t = 0.1, (0, 0, 0.06) rad/s; "
    f"got {np.round(got, 6).tolist()}")
yaws = np.deg2rad([170.0, -170.0, -150.0])
got = np.asarray(angular_velocities(np.array([1.0, -1.0, 1.0])[:, None] * Q.from_yaw(yaws),
                                    [0.0, 0.5, 1.0]))
assert np.allclose(got, [[0.0, 0.0, 0.698132]], atol=1e-6), (
    f"yaw 170, -170, -150 deg at t = 0, 0.5, 1 s, the middle one logged as -q: expected the "
    f"short turn, (0, 0, 0.698132) rad/s at t = 0.5 s; got {np.round(got, 6).tolist()}")
### BEGIN HIDDEN TESTS
test_rng = np.random.default_rng(440)  # the tests' own draws, not the notebook's rng
for _ in range(5):       # a rate linear in time about a fixed axis: exact on any clock
    times = np.concatenate([[0.0], np.cumsum(test_rng.uniform(0.05, 0.3, 20))])
    c1, c2 = test_rng.uniform(-1.5, 1.5), test_rng.uniform(-0.25, 0.25)   # turns below pi
    axis = Q.normalize(np.concatenate([[0.0], test_rng.normal(size=3)]))[1:]
    angle = c1 * times + c2 * times ** 2
    logged = (np.where(test_rng.random((21, 1)) < 0.5, -1.0, 1.0)
              * Q.multiply(Q.exp(angle[:, None] * axis), random_unit(1, test_rng)[0]))
    want = (c1 + 2.0 * c2 * times[1:-1])[:, None] * 2.0 * axis
    got = np.asarray(angular_velocities(logged, times))
    assert got.shape == (19, 3), f"21 orientations: expected shape (19, 3); got {got.shape}"
    bad = int(np.argmax(np.abs(got - want).max(axis=-1)))
    assert np.allclose(got, want, atol=1e-9), (
        f"a rate changing linearly about a fixed axis, irregular clock, random signs: at "
        f"t = {times[bad + 1]:.3f} expected {np.round(want[bad], 6)}; got {np.round(got[bad], 6)}")
w1, w2 = test_rng.normal(size=(2, 3))
w1, w2 = w1 / np.linalg.norm(w1), w2 / np.linalg.norm(w2)
for gap, tol in ((0.1, 4e-3), (0.05, 1e-3)):   # q(t) = exp(t/2 w1) * exp(t/2 w2): a turning axis
    times = np.concatenate([[0.0], np.cumsum(gap * test_rng.uniform(0.5, 1.5, 40))])
    A = Q.exp(0.5 * times[:, None] * w1)
    logged = (np.where(test_rng.random((41, 1)) < 0.5, -1.0, 1.0)
              * Q.multiply(A, Q.exp(0.5 * times[:, None] * w2)))
    want = w1 + Q.rotate(A[1:-1], np.broadcast_to(w2, (39, 3)))
    err = np.abs(np.asarray(angular_velocities(logged, times)) - want).max()
    assert err < tol, (
        f"a 3-D path whose rotation axis turns, irregular gaps around {gap} s: expected an "
        f"error below {tol:.0e} rad/s (second order in the gaps); got {err:.2e}")
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 4.5 — the sign guard between logged steps: its limit, and a better one
# The authors' environment repairs a logged sequence step by step: it flips $q_t$ to
# $-q_t$ whenever $\lVert q_t - q_{t-1}\rVert > 1.8$, against the previous quaternion
# *after* its own repair. Such a norm rule with a threshold $c$ works only while the
# true step between two samples rotates by less than some angle: beyond it, either a
# sign jump slips through or a genuine step gets flipped.
#
# 1. `guard_limit(c)`: the largest rotation angle $\varphi \in [0, \pi]$ (radians) per
#    step up to which the rule with threshold $c$ (with $0 < c < 2$) repairs every sign
#    jump and never flips a genuine step. (1 point)
# 2. `sign_continuous(qs)`: a repair of your design for `qs` of shape `(T, 4)` that
#    keeps `qs[0]` and makes the sequence sign-continuous for **every** step below
#    π; return a new array (do not modify `qs`). (1 point)
#
# <details><summary>Hint 1 (the idea)</summary>
#
# For unit quaternions $\lVert q - p\rVert^2 = 2 - 2\,q\cdot p$, and $q \cdot p =
# \cos(\varphi/2)$ for a genuine step by $\varphi$. What is the distance after a sign jump?
# </details>
#
# <details><summary>Hint 2 (the method)</summary>
#
# Write one inequality for "the jump is caught" and one for "the genuine step is
# kept"; the limit is where the first of them fails. Which threshold makes both hold
# up to π, and what does it test in terms of $q \cdot p$?
# </details>

# %% solution id=ex04_5 title="The sign guard's limit and a better guard"
def guard_limit(c):
    ### BEGIN SOLUTION
    caught = 2.0 * math.acos(max(-1.0, min(1.0, c * c / 2.0 - 1.0)))   # 2 + 2 cos(phi/2) > c^2
    kept = 2.0 * math.acos(max(-1.0, min(1.0, 1.0 - c * c / 2.0)))     # 2 - 2 cos(phi/2) <= c^2
    return min(caught, kept, math.pi)
    ### END SOLUTION


def sign_continuous(qs):
    ### BEGIN SOLUTION
    qs = np.asarray(qs, dtype=float)
    out = [qs[0]]
    for q in qs[1:]:
        out.append(-q if np.dot(q, out[-1]) < 0 else q)
    return np.array(out)
    ### END SOLUTION

# %% grade id=ex04_5_limit_tests points=1
got = guard_limit(1.8)
assert np.isclose(got, 1.804107), \
    f"the authors' threshold 1.8: expected 1.804107 rad (103.37 deg); got {got!r}"
got = guard_limit(1.0)
assert np.isclose(got, 2.094395), f"threshold 1: expected 2.094395 rad (120 deg); got {got!r}"
### BEGIN HIDDEN TESTS
for c in (0.5, 1.2, math.sqrt(2), 1.6, 1.95):
    phis = np.linspace(0.0, np.pi, 20001)[1:]
    p, step = ID, Q.from_axis_angle(np.array([0.3, -0.5, 0.8]), phis)   # genuine steps by phi
    jump_caught = np.linalg.norm(-step - p, axis=-1) > c
    genuine_kept = np.linalg.norm(step - p, axis=-1) <= c
    ok = jump_caught & genuine_kept
    want = phis[np.argmin(ok)] if not ok.all() else np.pi
    got = guard_limit(c)
    assert abs(got - want) < 2e-4, f"threshold {c:.4f}: expected {want:.4f} rad; got {got!r}"
### END HIDDEN TESTS

# %% grade id=ex04_5_tests points=1
psi = np.linspace(0.0, 4 * np.pi, 41)          # two full turns, 18 deg per step
smooth = Q.from_yaw(psi)                       # continuous: (cos psi/2, 0, 0, sin psi/2)
signs = np.where(np.random.default_rng(45).random(41) < 0.5, -1.0, 1.0)
signs[0] = 1.0
logged = signs[:, None] * smooth
fixed = sign_continuous(logged)
assert np.shape(fixed) == (41, 4), f"expected shape (41, 4); got {np.shape(fixed)}"
wrong = np.flatnonzero(~np.isclose(np.asarray(fixed), smooth).all(axis=-1))
assert len(wrong) == 0, (
    f"two yaw turns, 18 deg per step, random sign jumps: expected the continuous sequence; "
    f"steps {wrong[:5].tolist()} differ")
assert np.allclose(logged, signs[:, None] * smooth), (
    "expected sign_continuous to leave its input unchanged; got the input modified in place")
### BEGIN HIDDEN TESTS
rng_s = np.random.default_rng(451)
path = [random_unit(1, rng_s)[0]]
for _ in range(60):                            # a 3-D path with steps up to 170 deg
    axis = rng_s.normal(size=3)
    path.append(Q.multiply(Q.from_axis_angle(axis / np.linalg.norm(axis),
                                             rng_s.uniform(0.5, 2.97)), path[-1]))
path = np.array(path)
s = np.where(rng_s.random(61) < 0.5, -1.0, 1.0)
out = np.asarray(sign_continuous(s[:, None] * path))
same = np.isclose(out, s[0] * path).all(axis=-1) if out.shape == path.shape else [False]
wrong = np.flatnonzero(~np.asarray(same))
assert len(wrong) == 0, (
    f"a random 3-D path with steps of 30 to 170 deg and random sign jumps: expected the "
    f"continuous path with the sign of its first sample; {len(wrong)} of 61 samples differ, "
    f"first at step {wrong[0] if len(wrong) else -1}")
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 4.6 — integrating angular velocities measured in the body frame
# Eq. 5 takes η in the **world** frame. A car's gyroscope measures its angular
# velocity $\omega$ in its **own** axes (x forward, y left, z up, turning with the car).
# Derive the update for body-frame rates and write `integrate_body_rates(q0, omegas,
# dt)`: `q0` of shape `(4,)`, `omegas` of shape `(K, 3)` (body frame, rad/s, each held
# for `dt`); return the orientations $q_0, \dots, q_K$, shape `(K + 1, 4)`, renormalised
# every step so that rounding cannot carry them off the sphere.
#
# <details><summary>Hint 1 (the idea)</summary>
#
# A vector with body coordinates $\omega$ has the world coordinates $q\,(0, \omega)\,\bar q$.
# Put that into eq. 5 and simplify the product.
# </details>
#
# <details><summary>Hint 2 (the method)</summary>
#
# $\exp$ of a rotated vector is the rotated quaternion: $\exp(q\,u\,\bar q) = q\,\exp(u)\,\bar q$.
# What is left of $q\,\exp(u)\,\bar q * q$?
# </details>

# %% solution id=ex04_6 title="Integrating body-frame angular velocities"
def integrate_body_rates(q0, omegas, dt):
    ### BEGIN SOLUTION
    qs = [np.asarray(q0, dtype=float)]
    for omega in np.asarray(omegas, dtype=float):
        q = Q.multiply(qs[-1], Q.exp(0.5 * dt * omega))   # body frame: multiply on the right
        qs.append(q / np.linalg.norm(q))
    return np.array(qs)
    ### END SOLUTION

# %% grade id=ex04_6_tests points=3
traj = np.asarray(integrate_body_rates(Q.from_yaw(np.pi / 2), np.array([[np.pi, 0.0, 0.0]]), 0.5))
assert np.shape(traj) == (2, 4), f"K = 1 step: expected 2 orientations; got {np.shape(traj)}"
assert np.allclose(traj[1], [0.5, 0.5, 0.5, 0.5]), (
    f"facing yaw 90 deg, rolling about the car's own x axis at pi rad/s for 0.5 s: expected "
    f"(0.5, 0.5, 0.5, 0.5); got {np.round(traj[1], 4)}")
traj = np.asarray(integrate_body_rates(ID, np.tile([0.0, 0.0, 0.4], (10, 1)), 0.5))
assert np.allclose(Q.to_yaw(traj[-1]), 2.0), \
    f"a yaw rate of 0.4 rad/s for 10 steps of 0.5 s: expected yaw 2.0; got {Q.to_yaw(traj[-1])}"
### BEGIN HIDDEN TESTS
test_rng = np.random.default_rng(460)  # the tests' own draws, not the notebook's rng
q0_r = random_unit(1, test_rng)[0]
om_r = test_rng.normal(size=(300, 3)) * 2.0
got = np.asarray(integrate_body_rates(q0_r, om_r, 0.1))
world, q = [q0_r], q0_r
for om in om_r:   # the same motion in the world frame: rotate each rate by the current q
    eta = Q.multiply(Q.multiply(q, np.concatenate([[0.0], om])), Q.conjugate(q))[1:]
    q = Q.multiply(Q.exp(0.05 * eta), q)
    world.append(q / np.linalg.norm(q))
world = np.array(world)
assert got.shape == (301, 4), f"300 steps: expected shape (301, 4); got {got.shape}"
bad = int(np.argmax(np.abs(got - world).max(axis=-1)))
assert np.allclose(got, world, atol=1e-9), (
    f"300 random body rates: at step {bad} expected {np.round(world[bad], 4)} (the world-frame "
    f"rates written out); got {np.round(got[bad], 4)}")
drift = np.abs(np.linalg.norm(got, axis=1) - 1).max()
assert drift < 1e-12, f"expected |q| = 1 (renormalise); got |q| off by {drift:.2e}"
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 4.7 — a turning goal: how far behind does the DMP stay?
# The tutorial's goals stand still. Let the goal turn at a constant angular
# velocity $\omega_g$ (rad/s, world frame), $g(t) = \exp(\tfrac t2\,\omega_g) * g_0$,
# and run the quaternion DMP of section 5 against it (τ = 1, no forcing term):
# $\dot{\boldsymbol\eta} = \alpha(\beta\, e - \boldsymbol\eta)$ with
# $e$ = `orientation_error(g(t), q)`, $\dot q = \tfrac12\eta * q$. After the start
# is forgotten, the DMP follows the goal at a constant offset: the error
# rotation vector tends to a constant $e_\infty$.
#
# Write `steady_lag(omega_g, alpha, beta)`: $e_\infty$ as an array `(3,)`, for
# gains in the stable box and $\lVert\omega_g\rVert/\beta < \pi/2$. The tests
# compare it with long simulations (the integrator of section 5, the goal
# evaluated at the start of every sub-step).
#
# <details><summary>Hint 1 (the idea)</summary>
#
# In the steady state nothing changes any more: neither η nor the error. What
# must η be so that q keeps pace with the goal?
# </details>
#
# <details><summary>Hint 2 (the method)</summary>
#
# Put $\dot{\boldsymbol\eta} = 0$ in the first line of eq. 2 and use the answer
# to hint 1. Check the direction of your $e_\infty$ too: which way does q
# trail the goal? Does α enter?
# </details>

# %% solution id=ex04_7 title="The steady lag behind a turning goal"
def steady_lag(omega_g, alpha, beta):
    ### BEGIN SOLUTION
    # steady state: q turns with the goal, eta = omega_g, and eta' = 0 gives beta e = eta
    return np.asarray(omega_g, dtype=float) / beta
    ### END SOLUTION

# %%
def goal_path(g0, omega_g, times):
    """The turning goal exp(t/2 omega_g) * g0 at each of ``times``, shape (len(times), 4)."""
    return Q.multiply(Q.exp(0.5 * np.asarray(times)[:, None] * omega_g), g0)

# %% grade id=ex04_7_tests points=3
# the reference is a simulation: the library's DMP, one sub-step of h per step, fed the
# goal at the start of each sub-step (30 s, the start is forgotten by then)
h7, n7 = 0.05, 600
om7, g07 = np.array([0.0, 0.0, 0.6]), Q.from_yaw(0.3)
sim7 = Q.quaternion_rollout(ID, np.zeros(3), goal_path(g07, om7, h7 * np.arange(n7)), 4.0, 2.0,
                            h7, n7, substeps=1, per_step=("g_q",))
ref7 = Q.orientation_error(goal_path(g07, om7, [h7 * n7])[0], sim7.q[-1])
got7 = steady_lag(om7, 4.0, 2.0)
assert np.shape(got7) == (3,), f"expected an array of shape (3,); got shape {np.shape(got7)}"
assert np.allclose(got7, ref7, atol=1e-6), (
    f"goal turning at omega_g = [0, 0, 0.6] rad/s, alpha = 4, beta = 2: expected "
    f"e_inf = {np.round(ref7, 4).tolist()} (the simulation's error after 30 s); "
    f"got {np.round(got7, 4).tolist()}")
### BEGIN HIDDEN TESTS
test_rng = np.random.default_rng(470)  # the tests' own draws, not the notebook's rng
for _ in range(6):
    om = test_rng.normal(size=3)
    om *= test_rng.uniform(0.1, 1.0) / np.linalg.norm(om)
    a, b = test_rng.uniform(2.0, 10.0), test_rng.uniform(1.0, 4.0)
    g0 = Q.normalize(test_rng.normal(size=4))
    q0 = Q.normalize(test_rng.normal(size=4))
    sim = Q.quaternion_rollout(q0, np.zeros(3), goal_path(g0, om, h7 * np.arange(n7)), a, b,
                               h7, n7, substeps=1, per_step=("g_q",))
    ref = Q.orientation_error(goal_path(g0, om, [h7 * n7])[0], sim.q[-1])
    got = steady_lag(om, a, b)
    assert np.allclose(got, ref, atol=1e-6), (
        f"omega_g = {np.round(om, 3).tolist()}, alpha = {a:.3f}, beta = {b:.3f}: expected "
        f"e_inf = {np.round(ref, 6).tolist()} (simulated, 30 s); got {np.round(got, 6).tolist()}")
got = steady_lag(np.zeros(3), 4.0, 1.0)
assert np.allclose(got, 0.0), f"a goal at rest (omega_g = 0): expected no lag, got {got}"
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 4.8 — open experiment: follow a turning goal without lag
# A car that must match the heading of a lane through a curve wants no lag at
# all. Design a DMP that follows the turning goal of 4.7 with **zero steady
# error**, knowing $\omega_g$. Write
# `tracking_rollout(q0, g0, omega_g, alpha, beta, dt, steps)`: η starts at 0,
# every step of `dt` is `dmp.DEFAULT_SUBSTEPS` semi-implicit sub-steps of
# $h$ = `dt / dmp.DEFAULT_SUBSTEPS` (first η, then $q \leftarrow \exp(\tfrac h2\eta) * q$,
# as `Q.quaternion_rollout` does), with the goal $g(t)$ taken at the start of each
# sub-step; return the orientations after every step, shape `(steps + 1, 4)`.
# How you change the η-equation is yours to choose. Checked automatically:
#
# * for $\omega_g = 0$ your rollout **is** the DMP of section 5
#   (`Q.quaternion_rollout` with the same arguments, to 1e-9);
# * for turning goals, the error to the goal after 30 s is below 1e-4 rad;
# * the orientation moves from `q0` like a DMP: started 2.5 rad from the goal
#   with α = 4, β = 1, it is still more than a quarter of that away after the
#   first step (returning the goal itself does not count).
#
# Then answer the written question below the grade cell.
#
# <details><summary>Hint 1 (the idea)</summary>
#
# In 4.7 the error had to be nonzero to keep η at $\omega_g$. What could
# supply that η instead of the error?
# </details>
#
# <details><summary>Hint 2 (the method)</summary>
#
# Write the η-equation with a term that is zero when $\omega_g = 0$, and check
# that $e = 0$, $\eta = \omega_g$ is a steady state of your discrete update.
# </details>

# %% solution id=ex04_8 title="Open experiment: a DMP that tracks a turning goal"
def tracking_rollout(q0, g0, omega_g, alpha, beta, dt, steps):
    ### BEGIN SOLUTION
    h = dt / dmp.DEFAULT_SUBSTEPS
    omega_g = np.asarray(omega_g, dtype=float)
    q, eta, qs = np.asarray(q0, dtype=float), np.zeros(3), [np.asarray(q0, dtype=float)]
    times = h * np.arange(steps * dmp.DEFAULT_SUBSTEPS)
    for n, g in enumerate(goal_path(g0, omega_g, times)):
        # feedforward: the goal's own angular velocity drives eta, the error only corrects
        eta = eta + h * alpha * (beta * Q.orientation_error(g, q) + omega_g - eta)
        q = Q.integrate(q, eta, h)
        if (n + 1) % dmp.DEFAULT_SUBSTEPS == 0:
            qs.append(q)
    return np.array(qs)
    ### END SOLUTION

# %% grade id=ex04_8_tests points=3
q08, g08 = Q.from_yaw(-1.0), Q.from_axis_angle(np.array([1.0, 0.0, 2.0]), 0.7)
rest = tracking_rollout(q08, g08, np.zeros(3), 4.0, 1.0, dmp.DT, 12)
lib8 = Q.quaternion_rollout(q08, np.zeros(3), g08, 4.0, 1.0, dmp.DT, 12).q
assert np.shape(rest) == (13, 4), f"12 steps: expected shape (13, 4); got {np.shape(rest)}"
assert np.allclose(rest, lib8, atol=1e-9, rtol=0), (
    f"omega_g = 0, alpha = 4, beta = 1: expected the DMP of section 5 (Q.quaternion_rollout); "
    f"largest difference {np.abs(np.asarray(rest) - lib8).max():.2e}")
om8 = np.array([0.0, 0.0, np.deg2rad(30.0)])          # a lane turning at 30 deg/s
track = tracking_rollout(q08, g08, om8, 4.0, 1.0, dmp.DT, 60)
err8 = np.linalg.norm(Q.orientation_error(goal_path(g08, om8, [60 * dmp.DT])[0], track[-1]))
assert err8 < 1e-4, (
    f"goal turning at 30 deg/s about z, alpha = 4, beta = 1: expected an error below 1e-4 rad "
    f"after 30 s; got {err8:.2e} rad (the plain DMP of 4.7 keeps a steady lag)")
### BEGIN HIDDEN TESTS
test_rng = np.random.default_rng(480)  # the tests' own draws, not the notebook's rng
for _ in range(4):
    om = test_rng.normal(size=3)
    om *= test_rng.uniform(0.2, 1.0) / np.linalg.norm(om)
    a, b = test_rng.uniform(2.0, 10.0), test_rng.uniform(1.0, 4.0)
    g0, q0 = Q.normalize(test_rng.normal(size=(2, 4)))
    out = np.asarray(tracking_rollout(q0, g0, om, a, b, dmp.DT, 60))
    assert out.shape == (61, 4), f"60 steps: expected shape (61, 4), got {out.shape}"
    assert np.allclose(out[0], q0), f"the first orientation must be q0; got {out[0]}"
    err = np.linalg.norm(Q.orientation_error(goal_path(g0, om, [60 * dmp.DT])[0], out[-1]))
    assert err < 1e-4, (
        f"omega_g = {np.round(om, 3).tolist()}, alpha = {a:.3f}, beta = {b:.3f}: expected an "
        f"error below 1e-4 rad after 30 s; got {err:.2e} rad")
    g0r = Q.normalize(test_rng.normal(size=4))
    rest = np.asarray(tracking_rollout(q0, g0r, np.zeros(3), a, b, dmp.DT, 8))
    lib = Q.quaternion_rollout(q0, np.zeros(3), g0r, a, b, dmp.DT, 8).q
    assert np.allclose(rest, lib, atol=1e-9, rtol=0), (
        f"omega_g = 0, alpha = {a:.3f}, beta = {b:.3f}: expected Q.quaternion_rollout; "
        f"largest difference {np.abs(rest - lib).max():.2e}")
axis = Q.normalize(np.concatenate([[0.0], test_rng.normal(size=3)]))[1:]
q0 = Q.multiply(Q.from_axis_angle(axis, -2.5), g08)    # 2.5 rad from the goal
out = np.asarray(tracking_rollout(q0, g08, om8, 4.0, 1.0, dmp.DT, 60))
e0, e1 = (np.linalg.norm(Q.orientation_error(goal_path(g08, om8, [k * dmp.DT])[0], out[k]))
          for k in (0, 1))
assert e1 > 0.25 * e0, (
    f"start 2.5 rad from the goal, alpha = 4, beta = 1: after one step of 0.5 s the DMP is "
    f"still about 1.8 rad away; expected at least {0.25 * e0:.2f} rad, got {e1:.2f} rad "
    f"(the rollout must move from q0 like a DMP, not jump to the goal)")
### END HIDDEN TESTS

# %% [markdown]
# **Written question (4.8).** What did you add to the η-equation, and why does
# it remove the lag of 4.7? Write the equation the error obeys now for a goal
# turning about a fixed axis, and compare it with eq. 12. What would MANC's
# network have to output, or know, to use your DMP on a curving road?

# %% [markdown] answer id=ex04_8_w title="Why the feedforward removes the lag" points=2
# ### BEGIN SOLUTION
# The plain DMP can keep η = ω_g only if the error supplies it: η̇ = 0 needs
# βe = η = ω_g, so e∞ = ω_g/β (4.7). Adding the goal's own angular velocity,
# η̇ = α(βe + ω_g − η), makes e = 0, η = ω_g a steady state: the feedforward
# supplies the turning rate and the error is left to correct deviations only.
# About a fixed axis (everything commutes), with ε = ψ_g − ψ and ε̇ = ω_g − η,
# ε̈ = −η̇ = −α(βε + ε̇): exactly eq. 12, ε̈ + αε̇ + αβε = 0, so the error
# decays as for a goal at rest, with the same damping ratio and the same
# stability box. MANC would have to know ω_g — the goal's rate (e.g. the lane's
# curvature times the speed), as an extra output of the head or an input
# (a velocity goal next to the orientation goal).
# ### END SOLUTION

# %% [markdown]
# ## Putting it together
# The library's quaternion DMP takes its error the short way, with the sign choice
# of 4.4. From here on the cells use `minimanc.quaternion`, so they run even while
# the exercises are open: the DMP turns a car from 170° to −170° through 180°.

# %%
r = Q.quaternion_rollout(Q.from_yaw(np.deg2rad(170.0)), np.zeros(3),
                         Q.from_yaw(np.deg2rad(-170.0)), 4.0, 1.0, steps=12)
yaw = np.rad2deg(np.unwrap(Q.to_yaw(r.q)))
print("yaw (deg):", np.round(yaw, 1))
assert np.isclose(yaw[-1], 190.0, atol=0.1) and np.all(np.diff(yaw) >= 0)

# %% [markdown]
# ## Your figure
# Left: the yaw rate recovered from a drive weaving across ±180°, logged on an irregular
# clock with its samples stored with random signs, by **your** `angular_velocities`
# (solid) over the true rate (dashed): a wrong sign choice shows as spikes of hundreds of
# °/s, a rate placed at the wrong instant as a curve shifted along t. Right: a
# goal turning at 30°/s. The plain DMP (dashed) trails it; goal − **your**
# `steady_lag` must run on top of it once the start is forgotten, and **your**
# `tracking_rollout` on the goal (dashed). A function that raises is named in the
# title.

# %%
def yaw_deg(qs):
    return np.rad2deg(np.unwrap(Q.to_yaw(np.asarray(qs))))


t_log = np.concatenate([[0.0], np.cumsum(dmp.DT * (1.0 + 0.5 * np.sin(1.7 * np.arange(16))))])
yaw_log = np.pi + 1.5 * np.sin(0.4 * t_log)              # weaving across +-180 deg
flips = np.where(np.random.default_rng(4).random(17) < 0.5, -1.0, 1.0)
logged_fig = flips[:, None] * Q.from_yaw(yaw_log)
rate_true = np.rad2deg(0.6 * np.cos(0.4 * t_log[1:-1]))  # d(yaw)/dt, written out
print(f"log gaps from {np.diff(t_log).min():.2f} s to {np.diff(t_log).max():.2f} s")
om_fig, n_fig, h_fig = np.array([0.0, 0.0, np.deg2rad(30.0)]), 24, dmp.DT / dmp.DEFAULT_SUBSTEPS
t_fig = np.arange(n_fig + 1) * dmp.DT
goal_yaw = yaw_deg(goal_path(ID, om_fig, t_fig))
plain = yaw_deg(Q.quaternion_rollout(ID, np.zeros(3), goal_path(ID, om_fig, h_fig * np.arange(
    10 * n_fig)), 4.0, 1.0, h_fig, 10 * n_fig, substeps=1, per_step=("g_q",)).q[::10])
lag_fig = plain - goal_yaw
settled = abs(lag_fig[-1] - lag_fig[-5]) < 0.1       # degrees, over the last 2 s
print(f"plain DMP: behind the goal {bool(lag_fig[-1] < 0)}, lag settled {settled}")
assert lag_fig[-1] < 0 and settled
fig, axes = plt.subplots(1, 2, figsize=(12, 3.8))
vx.plot_curve_attempts(t_log[1:-1], [
    ("angular_velocities",
     lambda: np.rad2deg(np.asarray(angular_velocities(logged_fig, t_log))[:, 2]), rate_true)],
    ax=axes[0], title="yaw rate from an irregular log with sign jumps (deg/s)")
vx.plot_curve_attempts(t_fig, [
    ("goal − steady_lag", lambda: goal_yaw - np.rad2deg(np.asarray(steady_lag(om_fig, 4.0,
                                                                              1.0))[2]), plain),
    ("tracking_rollout", lambda: yaw_deg(tracking_rollout(ID, ID, om_fig, 4.0, 1.0, dmp.DT,
                                                          n_fig)), goal_yaw)],
    ax=axes[1], title="a goal turning at 30°/s (dashed: plain DMP, goal)")
axes[0].set_ylabel("yaw rate (deg/s)")
axes[1].set_ylabel("unwrapped yaw (deg)")
for ax in axes:
    ax.set_xlabel("t (s)")
plt.show()
