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

import matplotlib.pyplot as plt
import numpy as np

from minimanc import dmp
from minimanc.viz.exercises import plot_stability_boundary

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
# `dmp.max_stable_alpha` is switched off while this exercise is graded.
#
# <details><summary>Hint 1 (the idea)</summary>
#
# Each regime gives one condition on α. Ask in which regime the bound is
# reached, and what the complex-root condition says about hβ.
# </details>
#
# <details><summary>Hint 2 (the method)</summary>
#
# Solve $1 - h\alpha + h^2\alpha\beta < 1$ for the complex roots and
# $h\lambda_{min} > -2$ for the real ones, then check which one binds at the
# border α = 4β. The answer is a one-line formula with one special case (mind
# the case h·β = 1 exactly).
# </details>

# %% solution id=ex03_3 title="Stable range of alpha for explicit Euler" forbids="minimanc.dmp.max_stable_alpha"  # noqa: E501
def max_stable_alpha_euler(beta, h):
    ### BEGIN SOLUTION
    if h * beta >= 1.0:
        return 0.0
    return 4.0 / (h * (2.0 - h * beta))
    ### END SOLUTION

# %% grade id=ex03_3_tests points=4
# the reference value comes from the spectral radius, by bisection on alpha
lo, hi = 1.0, 20.0  # stable at lo, unstable at hi (beta = 0.5, h = 0.5)
for _ in range(60):
    mid = 0.5 * (lo + hi)
    lo, hi = (mid, hi) if dmp.spectral_radius(mid, 0.5, 0.5, "euler", 1) < 1 else (lo, mid)
got = max_stable_alpha_euler(0.5, 0.5)
assert np.isclose(got, lo), f"beta=0.5, h=0.5: expected {lo:.4f} (bisection on rho), got {got!r}"
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
# `dmp.fit_forcing_weights` is switched off while this exercise is graded.
#
# <details><summary>Hint (if the rollout misses the demo)</summary>
#
# The basis is **not** normalised in step 4 (it is in $f$). If the rollout
# below misses the demo by metres, check the sign of the phase
# ($e^{-\alpha_x t}$, not $e^{+\alpha_x t}$) and that $s$ carries the factor x.
# </details>

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
# `dmp.max_stable_alpha` is switched off while this exercise is graded.
#
# <details><summary>Hint 1 (the idea)</summary>
#
# Write each of the three conditions as an inequality in α for fixed β and h;
# the stable range is where all three hold.
# </details>
#
# <details><summary>Hint 2 (the method)</summary>
#
# One of the three conditions always holds, one gives $h\alpha < 2$, and one
# gives the answer; check that the answer is always below $2/h$, so it is the
# one that binds.
# </details>

# %% solution id=ex03_5 title="Stable range of alpha for semi-implicit Euler" forbids="minimanc.dmp.max_stable_alpha"  # noqa: E501
def max_stable_alpha_semi_implicit(beta, h):
    ### BEGIN SOLUTION
    # 1 - tr + det = h² α β > 0 always; |det| < 1 ⟺ 0 < hα < 2;
    # 1 + tr + det = 4 − hα (2 + hβ) > 0 ⟺ α < 4 / (h (2 + hβ)) ≤ 2/h
    return 4.0 / (h * (2.0 + h * beta))
    ### END SOLUTION

# %% grade id=ex03_5_tests points=3
got = max_stable_alpha_semi_implicit(0.0, 0.5)
assert np.isclose(got, 4.0), f"beta -> 0, h = 0.5: expected 4.0, got {got!r}"
# the reference value comes from the spectral radius, by bisection on alpha
lo, hi = 1.0, 100.0  # stable at lo, unstable at hi (beta = 5, h = 0.05)
for _ in range(60):
    mid = 0.5 * (lo + hi)
    lo, hi = (mid, hi) if dmp.spectral_radius(mid, 5.0, 0.05, "semi_implicit", 1) < 1 else (lo, mid)
got = max_stable_alpha_semi_implicit(5.0, 0.05)
assert np.isclose(got, lo), \
    f"the package's corner beta = 5 at h = 0.05: expected {lo:.2f} (bisection on rho), got {got!r}"
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
# ## Exercise 3.6 — a new integrator: the stable range of α for one RK2 step
# The tutorial maps explicit Euler, semi-implicit Euler and RK4; the package
# has no second-order Runge–Kutta. Take **Heun's method** (RK2) for the state
# $x = [e, \dot e]$ of eq. (12), $\dot x = f(x)$ with
# $f(e, \dot e) = (\dot e,\; -\alpha\beta e - \alpha\dot e)$:
#
# $$k_1 = f(x), \qquad k_2 = f(x + h k_1), \qquad x' = x + \tfrac{h}{2}(k_1 + k_2).$$
#
# 1. `rk2_step_matrix(alpha, beta, h)`: the 2×2 NumPy array $M$ with
#    $x' = M x$ for one Heun step of `h` seconds (scalars α, β, h > 0).
# 2. `max_stable_alpha_rk2(beta, h)`: the supremum of the α for which one Heun
#    step of `h` is stable (spectral radius of $M$ below 1), as a float,
#    accurate to a relative 1e-6. For these gains the stable α form one
#    interval $0 < \alpha < \alpha_{max}$.
#
# Unlike 3.3 and 3.5 this bound need not be a formula: derive $M$, then find
# $\alpha_{max}$ numerically. The two functions are graded separately, 2 points each.
#
# <details><summary>Hint 1 (the idea)</summary>
#
# $f$ is linear, $f(x) = Ax$ with the matrix $A$ of exercise 3.3. Then every
# stage is a matrix times $x$, and so is the whole step.
# </details>
#
# <details><summary>Hint 2 (the method)</summary>
#
# Substitute $k_1 = Ax$ into $k_2$ and collect powers of $hA$. For the bound,
# the spectral radius is below 1 for small α and above 1 for large α: grow an
# upper end until it is unstable, then bisect.
# </details>

# %% solution id=ex03_6 title="Stable range of alpha for one RK2 (Heun) step"
def rk2_step_matrix(alpha, beta, h):
    ### BEGIN SOLUTION
    hA = h * np.array([[0.0, 1.0], [-alpha * beta, -alpha]])
    return np.eye(2) + hA + 0.5 * hA @ hA
    ### END SOLUTION


def max_stable_alpha_rk2(beta, h):
    ### BEGIN SOLUTION
    def stable(a):
        return np.abs(np.linalg.eigvals(rk2_step_matrix(a, beta, h))).max() < 1

    lo, hi = 0.0, 1.0 / h
    while stable(hi):
        lo, hi = hi, 2.0 * hi
    for _ in range(100):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if stable(mid) else (lo, mid)
    return float(lo)
    ### END SOLUTION

# %% grade id=ex03_6_matrix_tests points=2
M6 = rk2_step_matrix(4.0, 1.0, 0.5)
assert np.shape(M6) == (2, 2), f"expected a (2, 2) array, got shape {np.shape(M6)}"
assert np.allclose(M6, [[0.5, 0.0], [0.0, 0.5]]), \
    f"alpha=4, beta=1, h=0.5: expected [[0.5, 0], [0, 0.5]], got {np.round(M6, 4).tolist()}"
### BEGIN HIDDEN TESTS
test_rng = np.random.default_rng(360)  # the tests' own draws, not the notebook's rng
for a, b, h in test_rng.uniform((0.5, 0.05, 0.01), (30.0, 5.0, 0.5), size=(30, 3)):
    M = rk2_step_matrix(a, b, h)
    assert np.shape(M) == (2, 2), f"alpha={a:.3f}: expected shape (2, 2), got {np.shape(M)}"
    for x in np.eye(2):   # Heun's two stages, written out on the state
        f1 = np.array([x[1], -a * b * x[0] - a * x[1]])
        xm = x + h * f1
        f2 = np.array([xm[1], -a * b * xm[0] - a * xm[1]])
        expected = x + 0.5 * h * (f1 + f2)
        got = np.asarray(M) @ x
        assert np.allclose(got, expected, rtol=1e-10, atol=1e-12), (
            f"alpha={a:.3f}, beta={b:.3f}, h={h:.3f}, x = {x.tolist()}: expected "
            f"M @ x = {np.round(expected, 6).tolist()} (one Heun step), "
            f"got {np.round(got, 6).tolist()}")
### END HIDDEN TESTS

# %% grade id=ex03_6_bound_tests points=2
# checked by stepping Heun's method on the state by hand, not through your matrix
a6 = max_stable_alpha_rk2(3.0, 0.5)  # h*beta = 1.5: explicit Euler has no stable alpha here
for a, shrinks in ((0.98 * a6, True), (1.02 * a6, False)):
    x = np.array([1.0, 0.0])
    for _ in range(400):
        f1 = np.array([x[1], -3.0 * a * x[0] - a * x[1]])
        xm = x + 0.5 * f1
        f2 = np.array([xm[1], -3.0 * a * xm[0] - a * xm[1]])
        x = x + 0.25 * (f1 + f2)
    size = np.abs(x).max()
    assert (size < 1) == shrinks, (
        f"beta=3, h=0.5: your bound {a6!r}; 400 Heun steps at alpha = {a:.4f} should "
        f"{'shrink' if shrinks else 'grow'} the error, |x| = {size:.3g}")
### BEGIN HIDDEN TESTS
test_rng = np.random.default_rng(361)  # the tests' own draws, not the notebook's rng


def rho_heun(a, b, h):  # the tests' own step matrix
    hA = h * np.array([[0.0, 1.0], [-a * b, -a]])
    return np.abs(np.linalg.eigvals(np.eye(2) + hA + 0.5 * hA @ hA)).max()


for b in test_rng.uniform(0.05, 8.0, size=12):
    for h in (0.05, 0.25, 0.5):
        lo, hi = 1e-9, 1e4  # stable at lo, unstable at hi: bisection on rho
        for _ in range(200):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if rho_heun(mid, b, h) < 1 else (lo, mid)
        got = max_stable_alpha_rk2(b, h)
        assert type(got) is float, f"beta={b:.3f}, h={h}: expected a float, got {type(got)}"
        assert math.isclose(got, lo, rel_tol=1e-6), \
            f"beta={b:.3f}, h={h}: expected alpha_max = {lo:.6g}, got {got!r}"
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

# %% [markdown]
# ## Your figure
# The stability boundary at dt = 0.5 s with one sub-step, drawn from **your**
# bounds of 3.3 (explicit Euler), 3.5 (semi-implicit Euler) and 3.6 (RK2) as
# markers over the library's `dmp.max_stable_alpha` (lines; RK2 has no library
# line: compare it with Euler's). A gain pair is stable below its curve. A wrong
# bound shows as markers off their line; a function that still raises is named
# in the title.

# %%
plot_stability_boundary(
    {"your explicit Euler": lambda b: max_stable_alpha_euler(b, 0.5),
     "your semi-implicit Euler": lambda b: max_stable_alpha_semi_implicit(b, 0.5),
     "your RK2 (Heun)": lambda b: max_stable_alpha_rk2(b, 0.5)},
    {"explicit Euler": lambda b: dmp.max_stable_alpha(b, 0.5, "euler", 1),
     "semi-implicit Euler": lambda b: dmp.max_stable_alpha(b, 0.5, "semi_implicit", 1)},
    np.linspace(0.1, 8.0, 40), 0.5,
)
plt.show()
