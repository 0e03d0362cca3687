# %% [markdown]
# # Chapter 4 — Graded exercises: quaternion algebra, orientation error, integration, a turning goal
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
assert np.allclose(multiply(i, j), k) and np.allclose(multiply(j, i), -k), (
    f"expected i*j = k = [0, 0, 0, 1] and j*i = -k; got {multiply(i, j)} and {multiply(j, i)}")
assert np.allclose(multiply(i, i), -ID), f"expected i*i = -1 = [-1, 0, 0, 0]; got {multiply(i, i)}"
got = multiply(ID, [0.5, 0.5, 0.5, 0.5])
assert np.allclose(got, [0.5, 0.5, 0.5, 0.5]), (
    f"the identity (1, 0, 0, 0) times q = (0.5, 0.5, 0.5, 0.5): expected q; got {got}")
### BEGIN HIDDEN TESTS
test_rng = np.random.default_rng(410)  # the tests' own draws, not the notebook's rng
p, q = random_unit(50, test_rng), random_unit(50, test_rng)
w, x, y, z = np.moveaxis(p, -1, 0)
left = np.stack([np.stack([w, -x, -y, -z], -1), np.stack([x, w, -z, y], -1),
                 np.stack([y, z, w, -x], -1), np.stack([z, -y, x, w], -1)], -2)
got, expected = np.asarray(multiply(p, q)), np.einsum("nij,nj->ni", left, q)
bad = int(np.argmax(np.abs(got - expected).max(axis=-1))) if got.shape == expected.shape else 0
assert got.shape == expected.shape and np.allclose(got, expected), (
    f"a batch of 50 random unit p, q: expected p * q = L(p) q, e.g. sample {bad}: "
    f"{np.round(expected[bad], 4)}; got {np.round(got[bad], 4) if got.ndim == 2 else got.shape}")
shape = np.shape(multiply(p[:, None], q[None, :5]))
assert shape == (50, 5, 4), f"(50, 1, 4) times (1, 5, 4): expected shape (50, 5, 4); got {shape}"
norms = np.linalg.norm(multiply(p, q), axis=-1)
assert np.allclose(norms, 1.0), (
    f"unit p, q: expected |p * q| = 1; got norms from {norms.min():.4f} to {norms.max():.4f}")
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
assert np.allclose(quat_log(half), [0.0, 0.0, 0.3]), (
    f"log of (cos 0.3, 0, 0, sin 0.3) is the half-angle vector [0, 0, 0.3]; got {quat_log(half)}")
assert np.allclose(quat_log(ID), 0.0), f"log of the identity is [0, 0, 0]; got {quat_log(ID)}"
### BEGIN HIDDEN TESTS
test_rng = np.random.default_rng(420)  # the tests' own draws, not the notebook's rng
with warnings.catch_warnings():
    warnings.simplefilter("error")
    got = quat_log(ID)
    assert np.allclose(got, 0.0), f"the identity, warnings as errors: expected [0, 0, 0]; got {got}"
    qs = random_unit(100, test_rng)
    back = Q.exp(quat_log(qs))
    bad = int(np.argmax(np.abs(back - qs).max(axis=-1)))
    assert np.allclose(back, qs), (
        f"100 random unit q: expected exp(log q) = q, e.g. q = {np.round(qs[bad], 4)}; "
        f"got exp(log q) = {np.round(back[bad], 4)}")
    longest = np.linalg.norm(quat_log(qs), axis=-1).max()
    assert longest <= np.pi + 1e-12, (
        f"principal branch: expected |log q| = atan2(|u|, w) in [0, pi]; got {longest:.4f}")
    shape = np.shape(quat_log(qs.reshape(10, 10, 4)))
    assert shape == (10, 10, 3), f"a (10, 10, 4) batch: expected shape (10, 10, 3); got {shape}"
    tiny = np.array([np.cos(1e-9), np.sin(1e-9), 0.0, 0.0])
    got = quat_log(tiny)[0]
    assert np.isclose(got, 1e-9, rtol=1e-9), (
        f"a 2e-9 rad rotation about x: expected log = 1e-9 (use atan2(|u|, w); arccos(w) "
        f"gives 0); got {got!r}")
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
assert np.allclose(quat_exp(np.zeros(3)), ID), f"exp(0) = (1, 0, 0, 0); got {quat_exp(np.zeros(3))}"  # noqa: E501
got = quat_exp([0.0, 0.0, 0.3])
assert np.allclose(got, [np.cos(0.3), 0.0, 0.0, np.sin(0.3)]), (
    f"omega = [0, 0, 0.3]: expected (cos 0.3, 0, 0, sin 0.3) = (0.9553, 0, 0, 0.2955); got {got}")
got = quat_exp([np.pi / 2, 0.0, 0.0])
assert np.allclose(got, [0.0, 1.0, 0.0, 0.0]), (
    f"omega = [pi/2, 0, 0]: expected i = (0, 1, 0, 0); got {got}")
### BEGIN HIDDEN TESTS
test_rng = np.random.default_rng(430)  # the tests' own draws, not the notebook's rng
with warnings.catch_warnings():
    warnings.simplefilter("error")
    w = test_rng.normal(size=(100, 3))
    n = np.linalg.norm(w, axis=-1, keepdims=True)
    got, expected = np.asarray(quat_exp(w)), np.concatenate([np.cos(n), np.sin(n) * w / n], -1)
    bad = int(np.argmax(np.abs(got - expected).max(axis=-1))) if got.shape == expected.shape else 0
    assert got.shape == expected.shape and np.allclose(got, expected), (
        f"100 random omega, e.g. {np.round(w[bad], 4)}: expected (cos|w|, sin|w| w/|w|) = "
        f"{np.round(expected[bad], 4)}; "
        f"got {np.round(got[bad], 4) if got.ndim == 2 else got.shape}")
    w = w / np.linalg.norm(w, axis=-1, keepdims=True) * test_rng.uniform(0, 3.1, size=(100, 1))
    back = Q.log(quat_exp(w))
    bad = int(np.argmax(np.abs(back - w).max(axis=-1)))
    assert np.allclose(back, w), (
        f"|omega| < pi: expected log(exp w) = w, e.g. w = {np.round(w[bad], 4)}; "
        f"got {np.round(back[bad], 4)}")
    shape = np.shape(quat_exp(np.zeros((2, 5, 3))))
    assert shape == (2, 5, 4), (
        f"a (2, 5, 3) batch of zeros, warnings as errors: expected shape (2, 5, 4); got {shape}")
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
assert np.allclose(np.rad2deg(e), [0.0, 0.0, 20.0]), (
    f"from 170 deg to -170 deg is +20 deg about z, not -340; got {np.rad2deg(e)} deg")
got = orientation_error(ID, ID)
assert np.allclose(got, 0.0), f"g = q = identity: expected [0, 0, 0]; got {got}"
### BEGIN HIDDEN TESTS
test_rng = np.random.default_rng(440)  # the tests' own draws, not the notebook's rng
g, q = random_unit(100, test_rng), random_unit(100, test_rng)
e = np.asarray(orientation_error(g, q))
r = Q.multiply(g, Q.conjugate(q))
short = np.where(r[..., :1] < 0, -r, r)
got = Q.exp(e / 2)
bad = int(np.argmax(np.abs(got - short).max(axis=-1)))
assert np.allclose(got, short), (
    f"100 random g, q: expected exp(e / 2) = the w >= 0 representative of g q*, e.g. "
    f"{np.round(short[bad], 4)}; got {np.round(got[bad], 4)}")
longest = np.linalg.norm(e, axis=-1).max()
assert longest <= np.pi + 1e-12, f"expected the error angle |e| <= pi; got {longest:.4f}"
for name, other in (("-g", orientation_error(-g, q)), ("-q", orientation_error(g, -q))):
    diff = np.abs(np.asarray(other) - e).max()
    assert np.allclose(other, e), (
        f"{name} is the same rotation: expected the same error; largest change {diff:.3g}")
got = orientation_error(-ID, ID)
assert np.allclose(got, 0.0), f"g = -1 (the identity rotation), q = 1: expected 0; got {got}"
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 4.5 — the sign guard between logged steps
# A logged orientation sequence may jump from $q$ to $-q$ between two steps
# (both are the same rotation; a simulator or a conversion routine picks either
# sign). Differences and interpolation between consecutive samples then see
# a huge jump. The authors' environment repairs the log step by step: **flip
# $q_t$ to $-q_t$ whenever $\lVert q_t - q_{t-1}\rVert > 1.8$**, where $q_{t-1}$
# is the previous quaternion *after* its own repair. Write
# `sign_continuous(qs, threshold=1.8)` for `qs` of shape `(T, 4)`: keep `qs[0]`,
# apply the rule to every later step in order, return a new array (do not
# modify `qs`).
#
# Why 1.8? For unit quaternions $\lVert q - p\rVert^2 = 2 - 2\,q\cdot p$, and
# $q\cdot p = \pm\cos(\varphi/2)$ for the rotation $\varphi \in [0, \pi]$ that
# takes one to the other. A genuine step has $q\cdot p \ge 0$ and is never
# flipped; a sign jump is caught when $\cos(\varphi/2) > 0.62$, i.e. for steps
# that rotate by less than about 103° — always the case at a car's data rate.

# %% solution id=ex04_5 title="Sign continuity of a logged sequence"
def sign_continuous(qs, threshold=1.8):
    ### BEGIN SOLUTION
    qs = np.asarray(qs, dtype=float)
    out = [qs[0]]
    for q in qs[1:]:
        out.append(-q if np.linalg.norm(q - out[-1]) > threshold else q)
    return np.array(out)
    ### END SOLUTION

# %% grade id=ex04_5_tests points=2
psi = np.linspace(0.0, 4 * np.pi, 41)          # two full turns, 18 deg per step
smooth = Q.from_yaw(psi)                       # continuous: (cos psi/2, 0, 0, sin psi/2)
signs = np.where(np.random.default_rng(45).random(41) < 0.5, -1.0, 1.0)
signs[0] = 1.0
logged = signs[:, None] * smooth
fixed = sign_continuous(logged)
assert np.shape(fixed) == (41, 4), f"expected shape (41, 4); got {np.shape(fixed)}"
wrong = np.flatnonzero(~np.isclose(np.asarray(fixed), smooth).all(axis=-1))
assert np.allclose(fixed, smooth), (
    f"two yaw turns with random sign jumps: expected the continuous sequence (flip q_t when "
    f"|q_t - q_(t-1)| > 1.8, against the repaired q_(t-1)); steps {wrong[:5].tolist()} differ, "
    f"e.g. step {wrong[0]}: expected {np.round(smooth[wrong[0]], 3)}, got "
    f"{np.round(np.asarray(fixed)[wrong[0]], 3)}" if len(wrong) else "")
assert np.allclose(logged, signs[:, None] * smooth), (
    "expected sign_continuous to leave its input unchanged; got the input modified in place")
### BEGIN HIDDEN TESTS
rng_s = np.random.default_rng(451)
path = [random_unit(1, rng_s)[0]]
for _ in range(60):                            # a smooth 3-D path, steps of tens of degrees
    path.append(Q.integrate(path[-1], rng_s.normal(size=3) * 0.35, 1.0))
path = np.array(path)
s = np.where(rng_s.random(61) < 0.5, -1.0, 1.0)
out = np.asarray(sign_continuous(s[:, None] * path))
same = np.isclose(out, s[0] * path).all(axis=-1) if out.shape == path.shape else [False]
wrong = np.flatnonzero(~np.asarray(same))
assert len(wrong) == 0, (
    f"a random 3-D path with random sign jumps: expected the continuous path with the sign "
    f"of its first sample; {len(wrong)} of 61 samples differ, first at step {wrong[0]}")
q_a, q_b = ID, Q.from_yaw(np.deg2rad(126.0))   # a 126-deg step with a sign jump
kept = np.asarray(sign_continuous(np.stack([q_a, -q_b])))
assert np.allclose(kept[1], -q_b), (
    f"a 126-deg step with a sign jump, |q_t - q_(t-1)| = 1.70 < 1.8: expected it kept "
    f"({np.round(-q_b, 3)}; the rule only catches jumps across steps below about 103 deg); "
    f"got {np.round(kept[1], 3)}")
flipped = np.asarray(sign_continuous(np.stack([q_a, -q_b]), threshold=np.sqrt(2)))[1]
assert np.allclose(flipped, q_b), (
    f"the same step with threshold = sqrt(2) (flip whenever q_t . q_(t-1) < 0): expected "
    f"{np.round(q_b, 3)}; got {np.round(flipped, 3)}")
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 4.6 — integrating an angular velocity (eq. 5)
# Eq. 5 advances an orientation by the rotation an angular velocity η (rad/s,
# world frame) makes in δt: $q_{k+1} = \exp(\tfrac{\delta t}{2}\,\eta_k) * q_k$
# (the paper's $\eta/\tau$ with τ = 1), renormalised so that rounding cannot
# carry q off the sphere. Write `integrate_sequence(q0, etas, dt)` for `q0` of
# shape `(4,)` and `etas` of shape `(K, 3)`: return all orientations
# $q_0, \dots, q_K$, shape `(K + 1, 4)`. Left-multiply: η is in the world frame.
# You may use `Q.exp` and `Q.multiply` (or your functions above);
# `Q.integrate` is disabled while this exercise is graded.

# %% solution id=ex04_6 title="Integrating an angular velocity" forbids="minimanc.quaternion.integrate"  # noqa: E501
def integrate_sequence(q0, etas, dt):
    ### BEGIN SOLUTION
    qs = [np.asarray(q0, dtype=float)]
    for eta in np.asarray(etas, dtype=float):
        q = Q.multiply(Q.exp(0.5 * dt * eta), qs[-1])
        qs.append(q / np.linalg.norm(q))
    return np.array(qs)
    ### END SOLUTION

# %% grade id=ex04_6_tests points=3
eta_c = np.array([0.3, -0.5, 1.2])
traj = integrate_sequence(ID, np.tile(eta_c, (40, 1)), 0.5)
assert np.shape(traj) == (41, 4), f"K = 40 steps give K + 1 = 41 orientations; got {np.shape(traj)}"  # noqa: E501
assert np.allclose(traj[0], ID), f"expected the first orientation q0 = (1, 0, 0, 0); got {traj[0]}"
exact = Q.exp(40 * 0.5 * eta_c / 2)
assert np.allclose(traj[-1], exact), (
    f"a constant eta = [0.3, -0.5, 1.2], 40 steps of 0.5 s: expected the exact "
    f"q_K = exp(K dt eta / 2) q0 = {np.round(exact, 4)}; got {np.round(traj[-1], 4)}")
### BEGIN HIDDEN TESTS
x_rate, z_rate = np.array([np.pi, 0.0, 0.0]), np.array([0.0, 0.0, np.pi])
two = integrate_sequence(ID, np.stack([x_rate, z_rate]), 0.5)     # 90 deg about x, then z
world = Q.multiply(Q.exp(z_rate / 4), Q.exp(x_rate / 4))
assert np.allclose(two[-1], world), (
    f"90 deg about x, then about z (world frame, eq. 5 left-multiplies): expected "
    f"{np.round(world, 4)}; got {np.round(two[-1], 4)}")
q0_r = random_unit(1, np.random.default_rng(460))[0]
etas_r = np.random.default_rng(46).normal(size=(2000, 3)) * 3.0
long = integrate_sequence(q0_r, etas_r, 0.1)
drift = np.abs(np.linalg.norm(long, axis=1) - 1).max()
assert drift < 1e-12, (
    f"2000 random steps: expected |q| = 1 (renormalise); got |q| off by {drift:.2e}")
first = Q.multiply(Q.exp(0.05 * etas_r[0]), q0_r)
assert np.allclose(long[1], first), (
    f"expected q_1 = exp(dt/2 eta_0) q0 = {np.round(first, 4)}; got {np.round(long[1], 4)}")
k = 1234
step_k = Q.multiply(Q.exp(0.05 * etas_r[k]), long[k])
assert np.allclose(long[k + 1], step_k), (
    f"step {k}: expected q_(k+1) = exp(dt/2 eta_k) q_k = {np.round(step_k, 4)}; "
    f"got {np.round(long[k + 1], 4)}")
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
# The library's quaternion DMP uses exactly this error. From here on the cells
# use `minimanc.quaternion`, so they run even while the exercises are open: the
# DMP turns a car from 170° to −170° through 180°, the short way.

# %%
r = Q.quaternion_rollout(Q.from_yaw(np.deg2rad(170.0)), np.zeros(3),
                         Q.from_yaw(np.deg2rad(-170.0)), 4.0, 1.0, steps=12)
yaw = np.rad2deg(np.unwrap(Q.to_yaw(r.q)))
print("yaw (deg):", np.round(yaw, 1))
assert np.isclose(yaw[-1], 190.0, atol=0.1) and np.all(np.diff(yaw) >= 0)

# %% [markdown]
# ## Your figure
# Left: the turn from 170° to −170° of section 3, the DMP's error computed by
# **your** `orientation_error` (solid) over the library's (dashed): a wrong sign
# choice turns the long way, −340°. Right: a goal turning at 30°/s. The plain
# DMP (dashed) trails it; goal − **your** `steady_lag` must run on top of it
# once the start is forgotten, and **your** `tracking_rollout` on the goal
# (dashed). A function that raises is named in the title.

# %%
def yaw_deg(qs):
    return np.rad2deg(np.unwrap(Q.to_yaw(np.asarray(qs))))


def dmp_with_error(error, q, g, alpha, beta, steps, substeps=dmp.DEFAULT_SUBSTEPS):
    """Section 5's DMP with its error term computed by ``error``; yaw (deg) after each step."""
    eta, out, h = np.zeros(3), [q], dmp.DT / substeps
    for n in range(steps * substeps):
        eta = eta + h * alpha * (beta * np.asarray(error(g, q)) - eta)
        q = Q.integrate(q, eta, h)
        if (n + 1) % substeps == 0:
            out.append(q)
    return yaw_deg(out)


q170, g170 = Q.from_yaw(np.deg2rad(170.0)), Q.from_yaw(np.deg2rad(-170.0))
om_fig, n_fig, h_fig = np.array([0.0, 0.0, np.deg2rad(30.0)]), 24, dmp.DT / dmp.DEFAULT_SUBSTEPS
t_fig = np.arange(n_fig + 1) * dmp.DT
goal_yaw = yaw_deg(goal_path(ID, om_fig, t_fig))
plain = yaw_deg(Q.quaternion_rollout(ID, np.zeros(3), goal_path(ID, om_fig, h_fig * np.arange(
    10 * n_fig)), 4.0, 1.0, h_fig, 10 * n_fig, substeps=1, per_step=("g_q",)).q[::10])
print(f"plain DMP after {n_fig * dmp.DT:.0f} s: {plain[-1] - goal_yaw[-1]:.1f} deg from the goal")
assert abs(plain[-1] - goal_yaw[-1] + 30.0) < 0.5   # it trails by 30 deg/s over beta = 1
fig, axes = plt.subplots(1, 2, figsize=(12, 3.8))
vx.plot_curve_attempts(np.arange(17) * dmp.DT, [
    ("orientation_error", lambda: dmp_with_error(orientation_error, q170, g170, 4.0, 1.0, 16),
     dmp_with_error(Q.orientation_error, q170, g170, 4.0, 1.0, 16))],
    ax=axes[0], title="170° → −170°: the short way is +20°")
vx.plot_curve_attempts(t_fig, [
    ("goal − steady_lag", lambda: goal_yaw - np.rad2deg(np.asarray(steady_lag(om_fig, 4.0,
                                                                              1.0))[2]), plain),
    ("tracking_rollout", lambda: yaw_deg(tracking_rollout(ID, ID, om_fig, 4.0, 1.0, dmp.DT,
                                                          n_fig)), goal_yaw)],
    ax=axes[1], title="a goal turning at 30°/s (dashed: plain DMP, goal)")
for ax in axes:
    ax.set_xlabel("t (s)")
    ax.set_ylabel("unwrapped yaw (deg)")
plt.show()
