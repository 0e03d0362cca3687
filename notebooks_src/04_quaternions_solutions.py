# %% [markdown]
# # Chapter 4 — Graded exercises: quaternion product, log, exp and orientation error
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
import warnings

import numpy as np

from minimanc import quaternion as Q

rng = np.random.default_rng(0)
ID = np.array([1.0, 0.0, 0.0, 0.0])


def random_unit(n):
    q = rng.normal(size=(n, 4))
    return q / np.linalg.norm(q, axis=-1, keepdims=True)

# %% [markdown]
# ## Exercise 4.1 — the quaternion product (eq. 3)
# $(v_1 + \mathbf u_1) * (v_2 + \mathbf u_2) = (v_1 v_2 - \mathbf u_1\cdot\mathbf u_2)
# + (v_1\mathbf u_2 + v_2\mathbf u_1 + \mathbf u_1\times\mathbf u_2)$.

# %% solution id=ex04_1 title="Quaternion product" forbids="minimanc.quaternion.multiply"
def multiply(p, q):
    ### BEGIN SOLUTION
    p, q = np.asarray(p, dtype=float), np.asarray(q, dtype=float)
    v1, u1 = p[..., :1], p[..., 1:]
    v2, u2 = q[..., :1], q[..., 1:]
    w = v1 * v2 - np.sum(u1 * u2, axis=-1, keepdims=True)
    u = v1 * u2 + v2 * u1 + np.cross(u1, u2)
    return np.concatenate([w, u], axis=-1)
    ### END SOLUTION

# %% grade id=ex04_1_tests points=2
i, j, k = np.eye(4)[1:]
assert np.allclose(multiply(i, j), k) and np.allclose(multiply(j, i), -k)
assert np.allclose(multiply(i, i), -ID)
assert np.allclose(multiply(ID, [0.5, 0.5, 0.5, 0.5]), [0.5, 0.5, 0.5, 0.5])
### BEGIN HIDDEN TESTS
p, q = random_unit(50), random_unit(50)
w, x, y, z = np.moveaxis(p, -1, 0)
left = np.stack([np.stack([w, -x, -y, -z], -1), np.stack([x, w, -z, y], -1),
                 np.stack([y, z, w, -x], -1), np.stack([z, -y, x, w], -1)], -2)
assert np.allclose(multiply(p, q), np.einsum("nij,nj->ni", left, q))   # p q = L(p) q
assert multiply(p[:, None], q[None, :5]).shape == (50, 5, 4)
assert np.allclose(np.linalg.norm(multiply(p, q), axis=-1), 1.0)
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 4.2 — the logarithmic map (eq. 4)
# $\log q = \theta\,\mathbf u / \lVert\mathbf u\rVert$ with the angle
# θ = `arctan2(‖u‖, w)` (the accurate form of `arccos(w)` for unit q), and
# $\log q = \mathbf 0$ when $\mathbf u = \mathbf 0$ (the identity). Return an
# array `(..., 3)`. No sign flip: θ lies in [0, π]. Inputs are unit
# quaternions other than −1. Avoid dividing by zero (no warnings!).

# %% solution id=ex04_2 title="Quaternion log" forbids="minimanc.quaternion.log"
def quat_log(q):
    ### BEGIN SOLUTION
    q = np.asarray(q, dtype=float)
    u = q[..., 1:]
    nu = np.linalg.norm(u, axis=-1, keepdims=True)
    theta = np.arctan2(nu, q[..., :1])
    safe = np.where(nu > 0, nu, 1.0)
    return np.where(nu > 0, theta * u / safe, 0.0)
    ### END SOLUTION

# %% grade id=ex04_2_tests points=3
half = np.array([np.cos(0.3), 0.0, 0.0, np.sin(0.3)])   # rotation by 0.6 rad about z
assert np.allclose(quat_log(half), [0.0, 0.0, 0.3])
assert np.allclose(quat_log(ID), 0.0)
### BEGIN HIDDEN TESTS
with warnings.catch_warnings():
    warnings.simplefilter("error")
    assert np.allclose(quat_log(ID), 0.0)
    qs = random_unit(100)
    assert np.allclose(Q.exp(quat_log(qs)), qs), "exp(log q) = q"
    assert np.all(np.linalg.norm(quat_log(qs), axis=-1) <= np.pi + 1e-12), "principal branch"
    assert quat_log(qs.reshape(10, 10, 4)).shape == (10, 10, 3)
    tiny = np.array([np.cos(1e-9), np.sin(1e-9), 0.0, 0.0])
    assert np.isclose(quat_log(tiny)[0], 1e-9, rtol=1e-9)   # arccos(w) would give 0
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 4.3 — the exponential map (eq. 6)
# $\exp\boldsymbol\omega = \cos\lVert\boldsymbol\omega\rVert + \sin\lVert\boldsymbol\omega\rVert\,
# \boldsymbol\omega/\lVert\boldsymbol\omega\rVert$, and $1 + \mathbf 0$ at ω = 0.
# `omega` has shape `(..., 3)`; return `(..., 4)`.

# %% solution id=ex04_3 title="Quaternion exp" forbids="minimanc.quaternion.exp"
def quat_exp(omega):
    ### BEGIN SOLUTION
    omega = np.asarray(omega, dtype=float)
    n = np.linalg.norm(omega, axis=-1, keepdims=True)
    safe = np.where(n > 0, n, 1.0)
    sinc = np.where(n > 0, np.sin(n) / safe, 1.0)
    return np.concatenate([np.cos(n), sinc * omega], axis=-1)
    ### END SOLUTION

# %% grade id=ex04_3_tests points=3
assert np.allclose(quat_exp(np.zeros(3)), ID)
assert np.allclose(quat_exp([0.0, 0.0, 0.3]), [np.cos(0.3), 0.0, 0.0, np.sin(0.3)])
assert np.allclose(quat_exp([np.pi / 2, 0.0, 0.0]), [0.0, 1.0, 0.0, 0.0])
### BEGIN HIDDEN TESTS
with warnings.catch_warnings():
    warnings.simplefilter("error")
    w = rng.normal(size=(100, 3))
    n = np.linalg.norm(w, axis=-1, keepdims=True)
    assert np.allclose(quat_exp(w), np.concatenate([np.cos(n), np.sin(n) * w / n], -1))
    assert np.allclose(np.linalg.norm(quat_exp(w), axis=-1), 1.0)
    w = w / np.linalg.norm(w, axis=-1, keepdims=True) * rng.uniform(0, 3.1, size=(100, 1))
    assert np.allclose(Q.log(quat_exp(w)), w)   # inverse of log for |w| < pi
    assert quat_exp(np.zeros((2, 5, 3))).shape == (2, 5, 4)
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 4.4 — the orientation error, the short way round
# The DMP's error term is $2\log(g * \bar q)$ (eq. 2): the rotation vector
# that turns q into g. But $g * \bar q$ and its negative are the same rotation,
# and their logs differ (θ versus π − θ). Pick the representative with
# $w \ge 0$ before taking the log, so that the error angle is at most π and
# the DMP turns the short way. You may use the library's `Q.multiply`,
# `Q.conjugate` and `Q.log` (or your own functions above). Shapes `(..., 4)`
# in, `(..., 3)` out.

# %% solution id=ex04_4 title="Orientation error with the sign choice" forbids="minimanc.quaternion.orientation_error"  # noqa: E501
def orientation_error(g, q):
    ### BEGIN SOLUTION
    r = Q.multiply(g, Q.conjugate(q))
    r = np.where(r[..., :1] < 0, -r, r)
    return 2.0 * Q.log(r)
    ### END SOLUTION

# %% grade id=ex04_4_tests points=4
e = orientation_error(Q.from_yaw(np.deg2rad(-170.0)), Q.from_yaw(np.deg2rad(170.0)))
assert np.allclose(np.rad2deg(e), [0.0, 0.0, 20.0]), np.rad2deg(e)   # not -340
assert np.allclose(orientation_error(ID, ID), 0.0)
### BEGIN HIDDEN TESTS
g, q = random_unit(100), random_unit(100)
e = orientation_error(g, q)
r = Q.multiply(g, Q.conjugate(q))
assert np.allclose(Q.exp(e / 2), np.where(r[..., :1] < 0, -r, r)), "exp(e / 2) = +-g q*"
assert np.all(np.linalg.norm(e, axis=-1) <= np.pi + 1e-12)
assert np.allclose(orientation_error(-g, q), e) and np.allclose(orientation_error(g, -q), e)
assert np.allclose(orientation_error(-ID, ID), 0.0)   # -1 is the identity rotation
### END HIDDEN TESTS

# %% [markdown]
# ## Putting it together
# The library's quaternion DMP uses exactly this error. From here on the cells
# use `minimanc.quaternion`, so they run even while the exercises are open: the
# DMP turns a car from 170° to −170° through 180°, the short way.

# %%
r = Q.quaternion_rollout(Q.from_yaw(np.deg2rad(170.0)), np.zeros(3),
                         Q.from_yaw(np.deg2rad(-170.0)), 4.0, 1.0, steps=12)
yaw = np.rad2deg(np.unwrap(Q.to_yaw(r.q)))
print("yaw (deg):", np.round(yaw, 1))
assert np.isclose(yaw[-1], 190.0, atol=0.1) and np.all(np.diff(yaw) >= 0)
