# %% [markdown]
# # Chapter 3 — Graded exercises: DMP damping, step stability, forcing term
#
# Module built in this chapter: **`minimanc.dmp`**. Read the tutorial
# `tutorials/03_dmp.ipynb` first. Replace each
# `raise NotImplementedError(...)` with your code and run the grade cell
# below it; `minimanc grade exercises/03_dmp.ipynb` scores the notebook.
#
# The point attractor of the paper (eq. 10) is
# $\ddot y = \alpha\,(\beta\,(g - y) - \dot y)$, i.e. eq. (12)
# $\ddot e + \alpha\dot e + \alpha\beta\, e = 0$ for $e = y - g$.

# %%
import math

import numpy as np

from minimanc import dmp, engine

rng = np.random.default_rng(0)

# %% [markdown]
# ## Exercise 3.1 — damping ratio and classification
# Write `damping_ratio(alpha, beta)` (eq. 13, $\zeta = \alpha / (2\sqrt{\alpha\beta})$,
# for α, β > 0) and `classify(alpha, beta)` returning one of
# `"underdamped"` (ζ < 1), `"critically damped"` (ζ = 1), `"overdamped"`
# (ζ > 1), or `"unstable"` when α ≤ 0 or β ≤ 0 (the system then does not
# converge to the goal). Scalars in, a float / a string out.
#
# ζ = 1 means α = 4β, which floating point rarely hits exactly: call the system
# critically damped when $|\alpha - 4\beta| \le 10^{-9}\,\alpha$ (the library's
# `dmp.CRITICAL_RTOL`; it is $|1 - 1/\zeta^2| \le 10^{-9}$), so ζ = 1 ± 1e-12 is
# critically damped and ζ = 1 ± 1e-8 is not. While this exercise is graded,
# `dmp.damping_ratio` and `dmp.classify` are switched off: write your own.
# The two functions are graded separately: `damping_ratio` 1 point, `classify` 2.

# %% solution id=ex03_1 title="Damping ratio and classification" forbids="minimanc.dmp.damping_ratio,minimanc.dmp.classify"  # noqa: E501
def damping_ratio(alpha, beta):
    ### BEGIN SOLUTION
    return alpha / (2.0 * np.sqrt(alpha * beta))
    ### END SOLUTION


def classify(alpha, beta):
    ### BEGIN SOLUTION
    if alpha <= 0 or beta <= 0:
        return "unstable"
    if abs(alpha - 4.0 * beta) <= 1e-9 * alpha:
        return "critically damped"
    return "underdamped" if damping_ratio(alpha, beta) < 1 else "overdamped"
    ### END SOLUTION

# %% grade id=ex03_1_zeta_tests points=1
z = damping_ratio(4.0, 1.0)
assert np.isclose(z, 1.0), f"alpha=4, beta=1: expected zeta = 4/(2*2) = 1, got {z!r}"
z = damping_ratio(1.0, 1.0)
assert np.isclose(z, 0.5), f"alpha=beta=1: expected zeta = 1/(2*1) = 0.5, got {z!r}"
### BEGIN HIDDEN TESTS
test_rng = np.random.default_rng(310)  # the tests' own draws, not the notebook's rng
for a, b in test_rng.uniform(0.01, 50, size=(200, 2)):
    z, expected = damping_ratio(a, b), 0.5 * np.sqrt(a / b)
    assert np.isclose(z, expected, rtol=1e-9), \
        f"alpha={a}, beta={b}: expected zeta = ½√(α/β) = {expected}, got {z!r}"
### END HIDDEN TESTS

# %% grade id=ex03_1_tests points=2
for (a, b), expected in (((4.0, 1.0), "critically damped"), ((1.0, 1.0), "underdamped"),
                         ((16.0, 1.0), "overdamped"), ((-1.0, 1.0), "unstable")):
    got = classify(a, b)
    assert got == expected, f"alpha={a}, beta={b}: expected {expected!r}, got {got!r}"
### BEGIN HIDDEN TESTS
test_rng = np.random.default_rng(311)  # the tests' own draws, not the notebook's rng
for b in (0.25, 1.0, 6.25, 40.0):   # zeta = 1 + d: alpha = 4 beta (1 + d)^2
    for d, expected in ((1e-12, "critically damped"), (-1e-12, "critically damped"),
                        (1e-10, "critically damped"), (-1e-10, "critically damped"),
                        (1e-8, "overdamped"), (-1e-8, "underdamped")):
        got = classify(4 * b * (1 + d) ** 2, b)
        assert got == expected, \
            f"beta={b}, zeta = 1 + {d:g}: expected {expected!r}, got {got!r}"
for a, b in test_rng.uniform(0.01, 50, size=(200, 2)):
    got, expected = classify(a, b), "underdamped" if a < 4 * b else "overdamped"
    assert got == expected, f"alpha={a}, beta={b}: expected {expected!r}, got {got!r}"
for a in test_rng.uniform(0.1, 50, size=20):
    got = classify(a, a / 4)
    assert got == "critically damped", \
        f"alpha={a}, beta = alpha/4: expected 'critically damped', got {got!r}"
for a, b in ((1.0, 0.0), (0.0, 1.0), (1.0, -3.0)):
    got = classify(a, b)
    assert got == "unstable", \
        f"alpha={a}, beta={b} (a gain <= 0): expected 'unstable', got {got!r}"
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 3.2 — one integrator step
# Advance eq. (10) by one step of `h` seconds, goal and gains held fixed.
# With $a(y, \dot y) = \alpha(\beta(g - y) - \dot y)$:
#
# * `method="euler"` (explicit): $y' = y + h\dot y$, $\dot y' = \dot y + h\,a(y, \dot y)$;
# * `method="semi_implicit"`: $\dot y' = \dot y + h\,a(y, \dot y)$, then $y' = y + h\,\dot y'$.
#
# Return `(y_next, dy_next)`. It must work on NumPy arrays of any shape
# (elementwise arithmetic only) and raise `ValueError` for any other method.
# `dmp.step` is switched off while this exercise is graded.

# %% solution id=ex03_2 title="One integrator step" forbids="minimanc.dmp.step"
def integrator_step(y, dy, goal, alpha, beta, h, method):
    ### BEGIN SOLUTION
    acc = alpha * (beta * (goal - y) - dy)
    if method == "euler":
        return y + h * dy, dy + h * acc
    if method == "semi_implicit":
        dy_next = dy + h * acc
        return y + h * dy_next, dy_next
    raise ValueError(f"unknown method {method!r}")
    ### END SOLUTION

# %% grade id=ex03_2_tests points=3
y1, dy1 = integrator_step(1.0, 0.0, 0.0, 4.0, 1.0, 0.5, "euler")
assert np.isclose(y1, 1.0) and np.isclose(dy1, -2.0), \
    f"euler from y=1, dy=0: expected y' = y + h*dy = 1, dy' = -2, got {y1!r}, {dy1!r}"
y1, dy1 = integrator_step(1.0, 0.0, 0.0, 4.0, 1.0, 0.5, "semi_implicit")
assert np.isclose(y1, 0.0) and np.isclose(dy1, -2.0), \
    f"semi_implicit: expected dy' = -2 first, then y' = y + h*dy' = 0, got {y1!r}, {dy1!r}"
try:
    integrator_step(1.0, 0.0, 0.0, 4.0, 1.0, 0.5, "leapfrog")
    raise AssertionError("method='leapfrog': expected a ValueError, got a return value")
except ValueError:
    pass
### BEGIN HIDDEN TESTS
test_rng = np.random.default_rng(320)  # the tests' own draws, not the notebook's rng
for method in ("euler", "semi_implicit"):
    y, dy, g = test_rng.normal(size=(3, 5, 2))
    a, b = test_rng.uniform(0.5, 10, size=(2, 5, 1))
    yn, dyn = integrator_step(y, dy, g, a, b, 0.1, method)
    ref_dy = dy + 0.1 * a * (b * (g - y) - dy)
    ref_y = y + 0.1 * (dy if method == "euler" else ref_dy)
    assert np.shape(yn) == (5, 2), f"{method}: expected shape (5, 2), got {np.shape(yn)}"
    np.testing.assert_allclose(dyn, ref_dy, err_msg=f"{method}, arrays (5, 2): dy'")
    np.testing.assert_allclose(yn, ref_y, err_msg=f"{method}, arrays (5, 2): y'")
dy1 = integrator_step(np.ones(3), 0.0, 0.0, 4.0, 1.0, 0.5, "euler")[1]
assert np.allclose(dy1, -2.0), \
    f"y = ones(3), scalar dy: expected dy' = -2 in every entry, got {dy1}"
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 3.3 — the stable range of α for explicit Euler
# One explicit Euler step maps $[e, \dot e]$ by $M = I + hA$ with
# $A = \begin{pmatrix} 0 & 1 \\ -\alpha\beta & -\alpha \end{pmatrix}$, so its
# eigenvalues are $1 + h\lambda$ for the roots λ of eq. (12). The step is
# stable iff $|1 + h\lambda| < 1$ for both roots. Work it out:
#
# * complex roots (α < 4β): $|1 + h\lambda|^2 = 1 - h\alpha + h^2\alpha\beta$;
# * real roots (α ≥ 4β): the more negative root must satisfy $h\lambda > -2$.
#
# Write `max_stable_alpha_euler(beta, h)` returning the supremum of the stable
# α (stable exactly for 0 < α < that value), or `0.0` if no α > 0 is stable.
# *Hint:* the answer is a one-line formula with one special case (mind the case
# h·β = 1 exactly). `dmp.max_stable_alpha` is switched off while this exercise
# is graded.

# %% solution id=ex03_3 title="Stable range of alpha for explicit Euler" forbids="minimanc.dmp.max_stable_alpha"  # noqa: E501
def max_stable_alpha_euler(beta, h):
    ### BEGIN SOLUTION
    if h * beta >= 1.0:
        return 0.0
    return 4.0 / (h * (2.0 - h * beta))
    ### END SOLUTION

# %% grade id=ex03_3_tests points=4
# critically damped systems (beta = alpha/4) need h*alpha < 4; at h = 0.5, beta = 0.5: ~4.57
got = max_stable_alpha_euler(0.5, 0.5)
assert np.isclose(got, 32 / 7), f"beta=0.5, h=0.5: expected 32/7 = 4.5714, got {got!r}"
got = max_stable_alpha_euler(3.0, 0.5)
assert got == 0.0, f"beta=3, h=0.5 (h*beta = 1.5 >= 1): expected 0.0, got {got!r}"
a_max = max_stable_alpha_euler(1.0, 0.25)
rho = dmp.spectral_radius(0.99 * a_max, 1.0, 0.25, "euler", 1)
assert rho < 1, f"beta=1, h=0.25: 0.99 x your bound {a_max!r} must be stable, rho = {rho:.4f}"
rho = dmp.spectral_radius(1.01 * a_max, 1.0, 0.25, "euler", 1)
assert rho > 1, f"beta=1, h=0.25: 1.01 x your bound {a_max!r} must be unstable, rho = {rho:.4f}"
### BEGIN HIDDEN TESTS
test_rng = np.random.default_rng(330)  # the tests' own draws, not the notebook's rng
for h, b in ((0.5, 2.0), (0.25, 4.0), (0.125, 8.0)):   # h*beta = 1 exactly: marginal
    got = max_stable_alpha_euler(b, h)
    assert got == 0.0, \
        f"beta={b}, h={h} (h*beta = 1): expected 0.0 (no alpha > 0 is stable), got {got!r}"
for b in test_rng.uniform(0.05, 5, size=30):
    for h in (0.05, 0.25, 0.5):
        got = max_stable_alpha_euler(b, h)
        expected = 0.0 if h * b >= 1 else 4.0 / (h * (2.0 - h * b))
        assert math.isclose(got, expected, rel_tol=1e-9), \
            f"beta={b}, h={h}: expected {expected}, got {got!r}"
for b, h, expected in ((1.5, 0.5, 6.4), (1e-6, 0.5, 4.0 / (0.5 * (2.0 - 5e-7)))):
    got = max_stable_alpha_euler(b, h)
    assert math.isclose(got, expected, rel_tol=1e-9), \
        f"beta={b}, h={h}: expected {expected}, got {got!r}"
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 3.4 — the forcing-term weights from one demonstration
# The full DMP of eq. (1) adds
# $f(x) = \frac{\sum_i \psi_i(x) w_i}{\sum_i \psi_i(x)}\, x\,(g - y_0)$, with the phase
# $x(t) = e^{-\alpha_x t}$ (τ = 1) and Gaussians $\psi_i(x) = e^{-h_i (x - c_i)^2}$.
# Write `lwr_weights(demo, dt, alpha, beta, centres, widths, alpha_x)` returning
# the weights, shape `(n_basis, D)`, for a demonstration `demo` of shape `(T + 1, D)`:
#
# 1. $y_0$ = `demo[0]`, $g$ = `demo[-1]`, $t_k = k\,\Delta t$, $x_k = e^{-\alpha_x t_k}$;
# 2. $\dot y, \ddot y$ by finite differences: `np.gradient(..., dt, axis=0, edge_order=2)`
#    (applied twice);
# 3. the target $f_{target} = \ddot y - \alpha(\beta(g - y) - \dot y)$ and $s = x\,(g - y_0)$;
# 4. locally weighted regression, each weight and dimension on its own:
#    $w_{id} = \frac{\sum_k \psi_i(x_k)\, s_{kd}\, f_{target,kd}}{\sum_k \psi_i(x_k)\, s_{kd}^2}$.
#
# *Hint:* the basis is **not** normalised in step 4 (it is in $f$). If the
# rollout below misses the demo by metres, check the sign of the phase
# ($e^{-\alpha_x t}$, not $e^{+\alpha_x t}$) and that $s$ carries the factor x.
# `dmp.fit_forcing_weights` is switched off while this exercise is graded.

# %% solution id=ex03_4 title="Forcing-term weights by locally weighted regression" forbids="minimanc.dmp.fit_forcing_weights"  # noqa: E501
def lwr_weights(demo, dt, alpha, beta, centres, widths, alpha_x):
    ### BEGIN SOLUTION
    y = np.asarray(demo, dtype=float)
    dy = np.gradient(y, dt, axis=0, edge_order=2)
    ddy = np.gradient(dy, dt, axis=0, edge_order=2)
    g, y0 = y[-1], y[0]
    x = np.exp(-alpha_x * np.arange(len(y)) * dt)
    psi = np.exp(-widths * (x[:, None] - centres) ** 2)  # (T + 1, n)
    f_target = ddy - alpha * (beta * (g - y) - dy)
    s = x[:, None] * (g - y0)
    return (psi.T @ (s * f_target)) / (psi.T @ (s * s))
    ### END SOLUTION

# %% grade id=ex03_4_tests points=3
t4 = np.arange(101) * 0.01
m4 = 10 * t4**3 - 15 * t4**4 + 6 * t4**5  # minimum jerk from 0 to 1 in 1 s
demo4 = np.stack([2 * m4, m4 + 0.8 * np.sin(np.pi * t4) ** 2], axis=-1)
ax4 = -np.log(0.01)  # the phase falls to 0.01 at t = 1 s
c4, h4 = dmp.basis_centres(30, ax4, 1.0)
w4 = lwr_weights(demo4, 0.01, 25.0, 6.25, c4, h4, ax4)
assert np.shape(w4) == (30, 2), \
    f"30 basis functions, D = 2: expected shape (30, 2) (n_basis, D), got {np.shape(w4)}"
r4 = dmp.rollout(demo4[0], np.zeros(2), demo4[-1], 25.0, 6.25, 0.01, 100,
                 forcing=dmp.Forcing(np.asarray(w4), c4, h4, ax4))
err4 = np.abs(r4.y - demo4).max()
assert err4 < 0.03, f"the fitted DMP should follow the demo within 3 cm, missed by {err4:.3f} m"
### BEGIN HIDDEN TESTS
# independent oracle: each w_id is a weighted least-squares fit, solved with lstsq
x4 = np.exp(-ax4 * t4)
dy4 = np.gradient(demo4, 0.01, axis=0, edge_order=2)
f4 = np.gradient(dy4, 0.01, axis=0, edge_order=2) - 25.0 * (6.25 * (demo4[-1] - demo4) - dy4)
s4 = x4[:, None] * (demo4[-1] - demo4[0])
for i in (0, 7, 29):
    sw = np.sqrt(np.exp(-h4[i] * (x4 - c4[i]) ** 2))
    for d in range(2):
        ref = np.linalg.lstsq((sw * s4[:, d])[:, None], sw * f4[:, d], rcond=None)[0][0]
        assert np.isclose(w4[i, d], ref, rtol=1e-8), \
            f"minimum-jerk demo: expected w[{i}, {d}] = {ref:.6g}, got {w4[i, d]!r}"
# another demo, other gains, 1-D, a different duration (dt = 0.02, 2 s)
t5 = np.arange(101) * 0.02
demo5 = (1 - np.cos(np.pi * t5 / 2.0))[:, None] * 1.5  # from 0 to 3, at rest at both ends
ax5 = -np.log(0.01) / 2.0  # x(2 s) = 0.01
c5, h5 = dmp.basis_centres(20, ax5, 2.0)
w5 = lwr_weights(demo5, 0.02, 10.0, 2.5, c5, h5, ax5)
r5 = dmp.rollout(demo5[0], np.zeros(1), demo5[-1], 10.0, 2.5, 0.02, 100,
                 forcing=dmp.Forcing(np.asarray(w5), c5, h5, ax5))
err5 = np.abs(r5.y - demo5).max()
assert err5 < 0.07, \
    f"a cosine reach from 0 to 3 m, dt = 0.02: expected within 7 cm, missed by {err5:.3f} m"
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 3.5 — the stable range of α for semi-implicit Euler
# The package integrates with semi-implicit Euler (velocity first, then the
# position with the new velocity). One sub-step of `h` maps $[e, \dot e]$ by
#
# $$M = \begin{pmatrix} 1 - h^2\alpha\beta & h(1 - h\alpha) \\
#                      -h\alpha\beta & 1 - h\alpha \end{pmatrix},
# \qquad \det M = 1 - h\alpha, \quad \mathrm{tr}\, M = 2 - h\alpha - h^2\alpha\beta.$$
#
# Jury's conditions say both eigenvalues of a 2×2 matrix lie strictly inside
# the unit circle iff $|\det M| < 1$, $1 - \mathrm{tr} + \det > 0$ and
# $1 + \mathrm{tr} + \det > 0$. Work them out for α, β > 0 and write
# `max_stable_alpha_semi_implicit(beta, h)`: the supremum of the stable α
# (stable exactly for 0 < α < that value).
#
# *Hint:* one of the three conditions always holds, one gives $h\alpha < 2$,
# and one gives the answer; check that the answer is always below $2/h$, so it
# is the one that binds. `dmp.max_stable_alpha` is switched off while this
# exercise is graded.

# %% solution id=ex03_5 title="Stable range of alpha for semi-implicit Euler" forbids="minimanc.dmp.max_stable_alpha"  # noqa: E501
def max_stable_alpha_semi_implicit(beta, h):
    ### BEGIN SOLUTION
    # 1 - tr + det = h² α β > 0 always; |det| < 1 ⟺ 0 < hα < 2;
    # 1 + tr + det = 4 − hα (2 + hβ) > 0 ⟺ α < 4 / (h (2 + hβ)) ≤ 2/h
    return 4.0 / (h * (2.0 + h * beta))
    ### END SOLUTION

# %% grade id=ex03_5_tests points=3
got = max_stable_alpha_semi_implicit(0.0, 0.5)
assert np.isclose(got, 4.0), f"beta -> 0, h = 0.5: expected 2/h = 4, got {got!r}"
got = max_stable_alpha_semi_implicit(5.0, 0.05)
assert np.isclose(got, 4 / (0.05 * 2.25)), \
    f"the package's corner beta = 5 at h = 0.05: expected 35.56, got {got!r}"
a5 = max_stable_alpha_semi_implicit(1.0, 0.25)
rho = dmp.spectral_radius(0.99 * a5, 1.0, 0.25, "semi_implicit", 1)
assert rho < 1, f"beta=1, h=0.25: 0.99 x your bound {a5!r} must be stable, rho = {rho:.4f}"
rho = dmp.spectral_radius(1.01 * a5, 1.0, 0.25, "semi_implicit", 1)
assert rho > 1, f"beta=1, h=0.25: 1.01 x your bound {a5!r} must be unstable, rho = {rho:.4f}"
### BEGIN HIDDEN TESTS
test_rng = np.random.default_rng(350)  # the tests' own draws, not the notebook's rng
for b in test_rng.uniform(0.05, 5, size=20):
    for h in (0.05, 0.25, 0.5):
        bound = max_stable_alpha_semi_implicit(b, h)
        for a, inside in ((0.995 * bound, True), (1.005 * bound, False)):
            M = np.array([[1 - h * h * a * b, h * (1 - h * a)], [-h * a * b, 1 - h * a]])
            rho = np.abs(np.linalg.eigvals(M)).max()  # the matrix written out, not the library
            assert (rho < 1) == inside, (
                f"beta={b:.3f}, h={h}: your bound {bound!r}; alpha = {a:.4f} should be "
                f"{'stable' if inside else 'unstable'}, got rho = {rho:.4f}")
got = max_stable_alpha_semi_implicit(2.0, 0.5)
assert math.isclose(got, 8 / 3, rel_tol=1e-9), f"beta=2, h=0.5: expected 8/3, got {got!r}"
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 3.6 — fit DMP gains to a target trajectory with `grad`
# A target velocity profile `target` (shape `(steps, 1)`) was made by
# `dmp.rollout(zeros(1), zeros(1), goal, α*, β*, dmp.DT, steps).dy[1:]` with
# unknown gains. Write `fit_gains(target, goal, steps, iters=60, lr=0.1)` that
# recovers them: optimise the two logits `z` (start at `z = zeros(2)`) of
# `dmp.gains_from_logits(z[0], z[1], xp=xp)` with Adam on the mean squared
# error between the rollout's velocities and `target`, differentiating the
# rollout with `eng = minimanc.engine("numpy")` (`eng.grad` or
# `eng.value_and_grad`, `xp = eng.xp`). Return `(alpha, beta)` as floats.
#
# Adam: `m = 0.9 m + 0.1 g`, `v = 0.999 v + 0.001 g²`,
# `z −= lr · (m / (1 − 0.9^k)) / (√(v / (1 − 0.999^k)) + 1e-12)` at iteration k = 1, 2, ….
#
# *Hint:* optimise the *logits*, not α and β themselves: a gradient step on the
# raw gains can make β negative or push α out of the stable range of the step,
# and the rollout then diverges (inside `grad` the gains are traced, so the
# stability check cannot stop it). The sigmoid keeps every iterate in the box.

# %% solution id=ex03_6 title="Fit DMP gains with grad through a rollout"
def fit_gains(target, goal, steps, iters=60, lr=0.1):
    ### BEGIN SOLUTION
    eng = engine("numpy")
    xp = eng.xp

    def loss(z):
        a, b = dmp.gains_from_logits(z[0], z[1], xp=xp)
        pred = dmp.rollout(xp.zeros(1), xp.zeros(1), goal, a, b, dmp.DT, steps, xp=xp).dy[1:]
        return xp.mean((pred - target) ** 2)

    z, m, v = np.zeros(2), np.zeros(2), np.zeros(2)
    for k in range(1, iters + 1):
        g = np.asarray(eng.grad(loss)(z))
        m = 0.9 * m + 0.1 * g
        v = 0.999 * v + 0.001 * g**2
        z = z - lr * (m / (1 - 0.9**k)) / (np.sqrt(v / (1 - 0.999**k)) + 1e-12)
    a, b = dmp.gains_from_logits(z[0], z[1])
    return float(a), float(b)
    ### END SOLUTION

# %% grade id=ex03_6_tests points=4
# target made with logits (-1, -0.5): alpha = 0.5 + 19.5 σ(-1), beta = 0.05 + 4.95 σ(-0.5)
a6_true = 0.5 + 19.5 / (1 + np.exp(1.0))
b6_true = 0.05 + 4.95 / (1 + np.exp(0.5))
target6 = dmp.rollout(np.zeros(1), np.zeros(1), 1.0, a6_true, b6_true, dmp.DT, 10).dy[1:]
a6, b6 = fit_gains(target6, 1.0, 10)
assert abs(a6 - a6_true) < 0.03 * a6_true, \
    f"10 steps to goal 1: expected alpha = {a6_true:.3f} within 3%, got {a6!r}"
assert abs(b6 - b6_true) < 0.03 * b6_true, \
    f"10 steps to goal 1: expected beta = {b6_true:.3f} within 3%, got {b6!r}"
### BEGIN HIDDEN TESTS
# other gains and a goal behind the start: alpha = 6, beta = 2 (inside the box), 12 steps
target7 = dmp.rollout(np.zeros(1), np.zeros(1), -1.0, 6.0, 2.0, dmp.DT, 12).dy[1:]
a7, b7 = fit_gains(target7, -1.0, 12, iters=80)
assert abs(a7 - 6.0) < 0.18 and abs(b7 - 2.0) < 0.06, \
    f"expected alpha = 6 +- 3%, beta = 2 +- 3%, got alpha={a7:.3f}, beta={b7:.3f}"
### END HIDDEN TESTS

# %% [markdown]
# ## Putting it together
# The library versions (`dmp.damping_ratio`, `dmp.classify`, `dmp.step`,
# `dmp.max_stable_alpha`) are used from here on, so this cell runs even while
# the exercises are open. The textbook gains, α = 25 with β = α/4, are
# critically damped but leave explicit Euler's stable range at 0.5 s:

# %%
a, b = 25.0, 25.0 / 4
print(dmp.classify(a, b), f"zeta={dmp.damping_ratio(a, b):.2f}")
a_lim = dmp.max_stable_alpha(b, 0.5, "euler", 1)  # h*beta = 3.1 >= 1: no alpha is stable
print(f"beta={b:.2f}: explicit Euler at dt=0.5 is stable for 0 < alpha < {a_lim:.3f}")
print(f"beta=alpha/4 family: stable while alpha < {4 / 0.5:.1f}")
print(f"spectral radius of one step: {dmp.spectral_radius(a, b, 0.5, 'euler', 1):.2f}")
y, dy, errors = 1.0, 0.0, [1.0]
for _ in range(6):  # six explicit Euler steps of dt = 0.5, written out
    y, dy = y + 0.5 * dy, dy + 0.5 * dmp.acceleration(y, dy, 0.0, a, b)
    errors.append(y)
print("errors:", " ".join(f"{e:.1f}" for e in errors))
assert abs(errors[-1]) > 1e3
