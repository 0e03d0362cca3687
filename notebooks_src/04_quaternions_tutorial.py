# %% [markdown]
# # Chapter 4 — Quaternions: log, exp and the quaternion DMP
#
# Module built in this chapter: **`minimanc.quaternion`** (product, conjugate,
# log and exp maps, integration, orientation error, conversions, and the
# quaternion DMP).
#
# A car's heading, like a robot hand's orientation, is not a point in a vector
# space: 359° and 1° are 2° apart, not 358°. The paper (after Abu-Dakka et al.)
# therefore writes the orientation part of its DMP with **unit quaternions**
# $q = [v, \mathbf u] \in S^3$ (eq. 2):
#
# $$\tau\dot{\boldsymbol\eta} = \alpha_q\big(\beta_q\; 2\log(g_q * \bar q) - \boldsymbol\eta\big)
#   + \mathbf f_q(s, x \mid \theta_q),
# \qquad \tau\dot q = \tfrac12\, \boldsymbol\eta * q,$$
#
# where η is the (scaled) angular velocity, τ a time constant and $\mathbf f_q$ a
# learned forcing term gated by the phase $x$ of chapter 3's canonical system.
# MANC drops the forcing term and lets the network output the gains, with τ
# folded into them (eq. 10); so from section 5 on this chapter integrates
# eq. 2 with $\tau = 1$ and $\mathbf f_q = 0$:
# $\dot{\boldsymbol\eta} = \alpha(\beta\, 2\log(g_q * \bar q) - \boldsymbol\eta)$,
# $\dot q = \tfrac12 \boldsymbol\eta * q$. This chapter builds the pieces: the product
# $*$ (eq. 3), the logarithm (eq. 4), the exponential (eq. 6), the integration
# rule (eq. 5) — and the traps: two quaternions per rotation, a logarithm that is
# undefined at −1, and a norm whose gradient is NaN at the identity.
#
# Convention: arrays `(..., 4)` in the order **(w, x, y, z)** (scipy uses
# (x, y, z, w)); a rotation by angle θ about the unit axis n is
# $q = (\cos\tfrac\theta2, \sin\tfrac\theta2\, n)$.
#
# **Objectives.** After this chapter you can
# - compute quaternion products, log and exp maps (eqs. 3–6) and orientation errors
# - integrate the quaternion DMP (eq. 2) and avoid its traps (two quaternions per rotation,
#   the log at −1, NaN gradients)
#
# **Prerequisites.** Chapter 3 (the point-attractor DMP); rotations in 3-D.
#
# **Time.** About 60 minutes for the tutorial and 120 for the exercises.

# %%
import warnings

import matplotlib.pyplot as plt
import numpy as np

from minimanc import dmp, engine
from minimanc import quaternion as Q

rng = np.random.default_rng(0)
ID = np.array([1.0, 0.0, 0.0, 0.0])

# %% [markdown]
# ## 1. The algebra
# The Hamilton product (eq. 3),
# $(v_1 + \mathbf u_1)(v_2 + \mathbf u_2) = (v_1v_2 - \mathbf u_1\!\cdot\mathbf u_2)
# + (v_1\mathbf u_2 + v_2\mathbf u_1 + \mathbf u_1\times\mathbf u_2)$,
# is associative but not commutative (the cross product): $ij = k$ but $ji = -k$.
# The conjugate $\bar q = v - \mathbf u$ inverts a unit quaternion, and a vector
# is rotated by sandwiching it as a pure quaternion: $q\,(0, \mathbf v)\,\bar q$.
# As rotations, $p * q$ applies $q$ first.

# %%
i, j, k = np.eye(4)[1:]
print("i*j =", Q.multiply(i, j), "  j*i =", Q.multiply(j, i), "  i*i =", Q.multiply(i, i))
p = Q.from_axis_angle(np.array([0.0, 0.0, 1.0]), np.pi / 2)   # 90° about z
q = Q.from_axis_angle(np.array([1.0, 0.0, 0.0]), np.pi / 2)   # 90° about x
v = np.array([0.0, 1.0, 0.0])
print("x-turn then z-turn of e_y:", np.round(Q.rotate(Q.multiply(p, q), v), 6) + 0.0)
print("z-turn then x-turn of e_y:", np.round(Q.rotate(Q.multiply(q, p), v), 6) + 0.0)
assert np.allclose(Q.rotate(Q.multiply(p, q), v), Q.rotate(p, Q.rotate(q, v)))
qs = Q.normalize(rng.normal(size=(1000, 4)))
vs = rng.normal(size=(1000, 3))
assert np.allclose(Q.multiply(qs, Q.conjugate(qs)), ID)
assert np.allclose(Q.rotate(qs, vs), np.einsum("nij,nj->ni", Q.to_matrix(qs), vs))
assert np.allclose(np.linalg.norm(Q.rotate(qs, vs), axis=1), np.linalg.norm(vs, axis=1))
print("q * conj(q) = 1, rotate == to_matrix, lengths preserved: checked on 1000 samples")

# %% [markdown]
# ## 2. log and exp: from the sphere to a flat space and back
# The unit quaternions form the 3-sphere $S^3$. Eq. (4) flattens it around the
# identity: $\log q = \arccos(v)\,\mathbf u / \lVert\mathbf u\rVert$, a vector of
# length θ/2 along the rotation axis (so $2\log q$ is the familiar rotation
# vector, axis × angle). Eq. (6) wraps it back:
# $\exp\boldsymbol\omega = \cos\lVert\boldsymbol\omega\rVert + \sin\lVert\boldsymbol\omega\rVert\,
# \boldsymbol\omega/\lVert\boldsymbol\omega\rVert$.
#
# We compute the angle as `atan2(‖u‖, w)` instead of `arccos(w)`: near the
# identity $w = \cos\epsilon \approx 1 - \epsilon^2/2$ rounds to 1 and
# `arccos` returns 0, losing small rotations entirely.
#
# All rotations about one axis n lie on a great circle of $S^3$,
# $(\cos\phi, \sin\phi\, n)$. The left figure draws that circle: exp wraps the
# tangent line at the identity around it; log unwraps it, but only one-to-one
# for $\lVert\omega\rVert < \pi$ — beyond, the line wraps round again.

# %%
n = np.array([0.0, 0.0, 1.0])
phis = np.linspace(-np.pi, np.pi, 9)[1:-1]
fig, axes = plt.subplots(1, 2, figsize=(12, 4.6))
ax = axes[0]
circle = np.linspace(0, 2 * np.pi, 200)
ax.plot(np.cos(circle), np.sin(circle), "k", lw=1)
ax.plot([1, 1], [-3.3, 3.3], color="tab:blue", lw=1, label="tangent space (ω along n)")
for phi in phis:
    qq = Q.exp(phi * n)
    ax.annotate("", xy=(qq[0], qq[3]), xytext=(1, phi),
                arrowprops=dict(arrowstyle="->", color="tab:orange", lw=0.8))
    ax.plot(1, phi, "o", color="tab:blue", ms=4)
    ax.plot(qq[0], qq[3], "o", color="tab:orange", ms=4)
    assert np.isclose(Q.log(qq)[2], phi)  # |ω| < π: log undoes exp
ax.plot(-1, 0, "rx", ms=10, mew=2, label="q = −1: log undefined")
ax.set_aspect("equal")
ax.set_xlabel("w")
ax.set_ylabel("z component of u")
ax.set_title("exp wraps the line onto the circle")
ax.legend(loc="lower left", fontsize=8)

omega = np.linspace(-2 * np.pi, 2 * np.pi, 801)[:, None] * n
ax = axes[1]
ok = ~np.isclose(np.abs(omega[:, 2]), np.pi)  # exp(±π n) = −1, where log is undefined
back = np.full(len(omega), np.nan)
back[ok] = Q.log(Q.exp(omega[ok]))[:, 2]
ax.plot(omega[:, 2], back, label="log(exp ω)")
ax.plot(omega[:, 2], omega[:, 2], "k--", lw=0.8, label="ω")
ax.axvspan(-np.pi, np.pi, color="tab:green", alpha=0.1, label="‖ω‖ < π: one-to-one")
ax.set_xlabel("ω (along n)")
ax.set_ylabel("log(exp ω)")
ax.legend(fontsize=8)
ax.set_title("exp is 2π-periodic; log returns |ω| ≤ π")
plt.show()

w_small = np.array([0.0, 0.0, 1e-9])
q_small = Q.exp(w_small)
print(f"w = cos(1e-9) rounds to {q_small[0]:.17f}")
print(f"arccos form: {np.arccos(q_small[0]):.3e}   atan2 form (Q.log): {Q.log(q_small)[2]:.3e}")
assert np.isclose(Q.log(q_small)[2], 1e-9, rtol=1e-12)

# %% [markdown]
# ## 3. The antipodal pitfall
# $q$ and $-q$ are the *same* rotation (the same matrix): $S^3$ covers the
# rotations twice. Their logarithms differ: for a rotation by θ, `log q` has
# length θ/2 but `log(−q)` has length π − θ/2 about the opposite axis — the
# same rotation reached the long way round. An orientation error computed
# naively as $2\log(g * \bar q)$ therefore may ask for a 340° turn where 20°
# in the other direction would do. `Q.orientation_error` picks the
# representative with $w \ge 0$ before taking the log, so the error angle is
# always at most π. (Logged data has the same issue from step to step; the
# authors' environment flips q whenever $\lVert q - q_{prev}\rVert > 1.8$.)

# %%
g = Q.from_yaw(np.deg2rad(-170.0))
q0 = Q.from_yaw(np.deg2rad(170.0))
assert np.allclose(Q.to_matrix(q0), Q.to_matrix(-q0))
naive = 2 * Q.log(Q.multiply(g, Q.conjugate(q0)))
short = Q.orientation_error(g, q0)
print(f"naive 2 log(g q̄): {np.rad2deg(naive[2]):8.2f} deg about z")
print(f"orientation_error: {np.rad2deg(short[2]):8.2f} deg about z")
assert np.isclose(np.rad2deg(short[2]), 20.0)


def naive_yaw_dmp(q, g, alpha, beta, dt, steps, substeps=10):
    """The quaternion DMP with the naive error (no sign choice), for comparison."""
    eta, out, h = np.zeros(3), [q], dt / substeps
    for _ in range(steps):
        for _ in range(substeps):
            eta = eta + h * alpha * (beta * 2 * Q.log(Q.multiply(g, Q.conjugate(q))) - eta)
            q = Q.integrate(q, eta, h)
        out.append(q)
    return np.array(out)


steps = 16
t = np.arange(steps + 1) * dmp.DT
bad = np.rad2deg(np.unwrap(Q.to_yaw(naive_yaw_dmp(q0, g, 4.0, 1.0, dmp.DT, steps))))
good = np.rad2deg(np.unwrap(Q.to_yaw(Q.quaternion_rollout(q0, np.zeros(3), g, 4.0, 1.0,
                                                          steps=steps).q)))
plt.figure(figsize=(7, 3.2))
plt.plot(t, bad, "o-", label="naive error: turns −340°")
plt.plot(t, good, "o-", label="orientation_error: turns +20°")
plt.axhline(190, color="k", lw=0.6, ls="--")
plt.axhline(-170, color="k", lw=0.6, ls="--")
plt.xlabel("t (s)")
plt.ylabel("unwrapped yaw (deg)")
plt.legend()
plt.show()
print(f"total turn: naive {bad[-1] - bad[0]:.1f} deg, ours {good[-1] - good[0]:.1f} deg")
assert abs(bad[-1] - bad[0] + 340) < 1 and abs(good[-1] - good[0] - 20) < 1

# %% [markdown]
# ## 4. Integrating an angular velocity
# Eq. (5) advances the orientation by the rotation the angular velocity makes
# in δt: $q(t + \delta t) = \exp(\tfrac{\delta t}{2}\,\eta/\tau) * q(t)$. (The paper
# introduces it with "Equation (4) can be integrated as"; what it integrates is
# the second line of eq. 2, $\tau\dot q = \tfrac12\eta * q$ — eq. 4 is the log map.) For a
# constant η this is exact after any number of steps, and it stays on the
# sphere up to rounding (we renormalise anyway). A first-order update of
# $\dot q = \tfrac12 \eta * q$, $q \leftarrow q + \tfrac{\delta t}2\, \eta * q$,
# leaves the sphere: its norm grows every step.

# %%
eta = np.array([0.3, -0.5, 1.2])  # rad/s
q_exp, q_lin = ID, ID
norms, errs_exp, errs_lin = [], [], []
dt, steps = 0.5, 40
for s in range(1, steps + 1):
    q_exp = Q.integrate(q_exp, eta, dt)
    q_lin = q_lin + 0.5 * dt * Q.multiply(np.concatenate([[0.0], eta]), q_lin)
    exact = Q.exp(s * dt * eta / 2)
    norms.append(np.linalg.norm(q_lin))
    errs_exp.append(np.linalg.norm(Q.orientation_error(exact, q_exp)))
    errs_lin.append(np.linalg.norm(Q.orientation_error(exact, Q.normalize(q_lin))))
fig, axes = plt.subplots(1, 2, figsize=(11, 3.3))
tt = np.arange(1, steps + 1) * dt
axes[0].plot(tt, norms, label="first-order update")
axes[0].axhline(1, color="k", lw=0.8, label="exp map (eq. 5)")
axes[0].set_ylabel("‖q‖")
axes[0].legend()
axes[1].semilogy(tt, np.array(errs_lin) + 1e-17, label="first-order, renormalised")
axes[1].semilogy(tt, np.array(errs_exp) + 1e-17, label="exp map")
axes[1].set_ylabel("angle to the exact orientation (rad)")
axes[1].legend()
for ax in axes:
    ax.set_xlabel("t (s)")
plt.show()
print(f"after {steps * dt:.0f} s: first-order norm {norms[-1]:.2f}, "
      f"its angle error {errs_lin[-1]:.3f} rad; exp-map angle error below 1e-12 rad: "
      f"{errs_exp[-1] < 1e-12}")
assert errs_exp[-1] < 1e-12 and norms[-1] > 2

# %% [markdown]
# ## 5. The quaternion DMP converges in 3-D
# `Q.quaternion_rollout` integrates eq. (2) with learned-style gains (eq. 10):
# per sub-step, $\eta \leftarrow \eta + h\,\alpha(\beta e - \eta)$ with
# $e$ = `orientation_error(g, q)`, then $q \leftarrow \exp(\tfrac h2\eta) * q$
# (semi-implicit, as in chapter 3, with the same default sub-steps and the
# same stable gain box). Below: the error rotation vector (axis × angle, the
# three components) from a random start to a random goal, for three damping
# ratios.

# %%
q_start = Q.from_axis_angle(np.array([1.0, 2.0, -1.0]), 2.6)
q_goal = Q.from_axis_angle(np.array([0.0, 0.0, 1.0]), -0.5)
eta0 = np.array([0.5, -1.0, 0.3])
steps = 24
t = np.arange(steps + 1) * dmp.DT
fig, axes = plt.subplots(1, 3, figsize=(13, 3.4), sharey=True)
for ax, (alpha, beta) in zip(axes, [(2.0, 2.0), (4.0, 1.0), (16.0, 1.0)]):
    r = Q.quaternion_rollout(q_start, eta0, q_goal, alpha, beta, dmp.DT, steps)
    err = Q.orientation_error(q_goal, r.q)  # (steps + 1, 3)
    for c, name in enumerate("xyz"):
        ax.plot(t, err[:, c], label=f"error {name}")
    ax.plot(t, np.linalg.norm(err, axis=1), "k--", lw=1, label="angle")
    zeta = dmp.damping_ratio(alpha, beta)
    ax.set_title(f"α = {alpha:g}, β = {beta:g} (ζ = {zeta:.2f})")
    ax.set_xlabel("t (s)")
    print(f"zeta={zeta:.2f}: angle to goal {np.linalg.norm(err[0]):.3f} -> "
          f"{np.linalg.norm(err[-1]):.1e} rad")
    assert np.linalg.norm(err[-1]) < 1e-2
axes[0].set_ylabel("rotation vector to goal (rad)")
axes[0].legend(fontsize=8)
plt.show()

# %% [markdown]
# ## 6. Yaw only: the quaternion DMP is the 1-D DMP on the wrapped yaw error
# A car only turns about the vertical axis. For rotations about z everything
# commutes, `orientation_error` is the yaw difference wrapped into (−π, π], and
# the quaternion DMP reduces *exactly* to chapter 3's DMP on the heading with
# that wrapped error. This is what lets MANC output a yaw rate from the same
# machinery.

# %%
psi0, psi_g, yaw_rate0 = 2.8, -2.9, -0.4   # the short way crosses ±π
alpha, beta, steps, sub = 3.0, 1.2, 20, dmp.DEFAULT_SUBSTEPS
r = Q.quaternion_rollout(Q.from_yaw(psi0), np.array([0.0, 0.0, yaw_rate0]), Q.from_yaw(psi_g),
                         alpha, beta, dmp.DT, steps)
psi, w, yaws = psi0, yaw_rate0, [psi0]
for _ in range(steps):
    for _ in range(sub):
        wrapped = np.angle(np.exp(1j * (psi_g - psi)))  # wrap into (−π, π]
        psi, w, _ = dmp.step(psi, w, psi + wrapped, alpha, beta, dmp.DT / sub, "semi_implicit", 1)
    yaws.append(psi)
yaw_q = np.unwrap(Q.to_yaw(r.q))
diff = np.max(np.abs(yaw_q - np.array(yaws)))
plt.figure(figsize=(7, 3.2))
plt.plot(np.arange(steps + 1) * dmp.DT, np.rad2deg(yaw_q), "o", label="quaternion DMP")
plt.plot(np.arange(steps + 1) * dmp.DT, np.rad2deg(yaws), "-", label="1-D DMP, wrapped error")
plt.axhline(np.rad2deg(psi_g + 2 * np.pi), color="k", lw=0.6, ls="--")
plt.xlabel("t (s)")
plt.ylabel("unwrapped yaw (deg)")
plt.legend()
plt.show()
print(f"largest difference between the two below 1e-9 rad: {diff < 1e-9}")
assert diff < 1e-9

# %% [markdown]
# ## 7. Gradients at the identity
# Behaviour cloning differentiates through all of this, and the DMP spends
# most of its time near its goal, where $g * \bar q \approx 1$ and
# $\mathbf u \approx 0$. The textbook formula divides by $\lVert\mathbf u\rVert$,
# and the derivative of $\sqrt{x}$ at 0 is infinite: even where the *value*
# is patched with `where`, the gradient of the unused branch is $0 \cdot \infty$
# = NaN. The fix is the "double where": feed the unused branch a harmless
# value ($\lVert\mathbf u\rVert^2 \to 1$), and use the series
# $\log q \approx \mathbf u / w$ near the identity, whose derivative is exact there.

# %%
eng = engine("numpy")
xp = eng.xp


def naive_log(q):
    u = q[1:]
    nu = xp.sqrt(xp.sum(u * u))
    return xp.where(nu > 0, xp.arccos(q[0]) * u / nu, 0.0 * u)


with warnings.catch_warnings(), np.errstate(all="ignore"):
    warnings.simplefilter("ignore")
    g_naive = eng.grad(lambda q: xp.sum(naive_log(q)))(ID)
g_ours = eng.grad(lambda q: xp.sum(Q.log(q, xp=xp)))(ID)
print("d sum(log q) / dq at the identity")
print("  naive   :", g_naive)
print("  Q.log   :", g_ours)
assert np.all(np.isnan(g_naive)) and np.allclose(g_ours, [0.0, 1.0, 1.0, 1.0])

# %% [markdown]
# ## Summary
# * Quaternions (w, x, y, z): `multiply` (eq. 3), `conjugate`, `rotate`, `to_matrix`.
# * `log` (eq. 4, atan2 form) and `exp` (eq. 6) are inverse for ‖ω‖ < π;
#   `log(−1)` is undefined and raises.
# * q and −q are one rotation: `orientation_error` takes the short way (w ≥ 0).
# * `integrate` (eq. 5) is exact for constant angular velocity and stays on the sphere.
# * `quaternion_rollout` is the orientation DMP; for yaw-only motion it is the 1-D
#   DMP of chapter 3 on the wrapped heading error.
# * Gradients are finite at the identity on both engines (double-where trick).

# %% [markdown]
# ## Paper vs. this course
# Where this chapter departs from section III-B of the paper (eqs. 2–6), and
# where the paper itself slips:
#
# * **Eq. 2 without τ and $\mathbf f_q$.** The paper's eq. 2 has a time constant
#   τ and a forcing term $\mathbf f_q(s, x \mid \theta_q)$. An earlier version of
#   this tutorial quoted it without either; the introduction now states it in
#   full. The course integrates eq. 2 with τ = 1 and no forcing term, because
#   MANC replaces the forcing term by learned gains and folds τ into them
#   (eq. 10); its head outputs α and β only.
# * **"Equation (4) can be integrated as" eq. 5** means eq. 2: eq. 5 integrates
#   the kinematics $\tau\dot q = \tfrac12\eta * q$; eq. 4 is the logarithm.
# * **Eq. 1's canonical system** reads $\tau\dot x = \alpha_x x$, which grows;
#   it should be $\tau\dot x = -\alpha_x x$ (the phase $x$ that would gate
#   $\mathbf f_q$ must decay); `minimanc.dmp` (chapter 3) uses the minus sign.
# * **Eq. 4's `arccos(v)`** loses small rotations in floating point
#   (`cos(1e-9)` rounds to 1, section 2). We compute the same angle as
#   `atan2(‖u‖, v)`, identical for unit q in exact arithmetic.
# * **"η ... treated as unit quaternion with zero scalar"**: η enters the
#   product as the *pure* quaternion $(0, \eta)$; it is not a unit quaternion
#   (its norm is the angular speed).
# * **Which sign of $g_q * \bar q$?** Eq. 2 does not say; taken literally it can
#   turn a car 340° the long way (section 3). `orientation_error` takes the
#   representative with $w \ge 0$. The paper's domain remark (log and Exp
#   inverse on $S^3 \setminus \{-1\}$, $\lVert\omega\rVert < \pi$) is about
#   quaternions; as *rotations*, q and −q coincide, and a unique rotation vector
#   needs $\lVert\omega\rVert \le \pi/2$, i.e. $w \ge 0$.
# * **Eq. 10's gains** are written $\alpha_y(s\mid\theta_q), \beta_y(s\mid\theta_q)$
#   and eq. 11's $\mathtt{FC}(q) = \{\alpha_y, \beta_y, \alpha_y, \beta_y\}$: the
#   last two should be the orientation gains $\alpha_q, \beta_q$.
# * **The sign guard $\lVert q - q_{prev}\rVert > 1.8$** comes from the authors'
#   environment, not the paper. It repairs a sign jump only across steps that
#   rotate by less than a limiting angle; exercise 4.5 derives the limit and
#   designs a guard without one.
# * **Gradients at the identity** are not discussed in the paper: eqs. 4 and
#   6 as written (a case split on $\mathbf u = 0$) give NaN gradients under
#   autodiff; our double `where` keeps them exact (section 7).
