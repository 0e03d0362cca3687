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
# ## Exercise 3.1 — gains for a damping ratio and a settling time
# The tutorial reads ζ and the motion off given gains. A designer goes the other
# way: *"critically damped, settled within 2 s"*. Write `gains_for(zeta, t_settle)`
# returning `(alpha, beta)`, two floats, such that the continuous system of eq. (12)
#
# * has the damping ratio `zeta` (eq. 13), and
# * its **slowest** characteristic root has the real part $-4/t_\text{settle}$, so
#   that the error's envelope shrinks by $e^{-4} \approx 1.8\,\%$ within `t_settle`.
#
# Both arguments are positive; ζ may lie on either side of 1. Graded in two parts:
# ζ ≤ 1 (1 point) and ζ > 1 (2 points).
#
# <details><summary>Hint 1 (the idea)</summary>
#
# Write the two roots of eq. (12) with $\omega_n = \sqrt{\alpha\beta}$ and ζ. When they
# are complex (or double), what is their real part? When they are real, which one
# is the slow one?
# </details>
#
# <details><summary>Hint 2 (the method)</summary>
#
# Solve for $\omega_n$ from the slow root in each regime, then recover α and β from
# $\omega_n$ and ζ. Check that both regimes agree at ζ = 1.
# </details>

# %% solution id=ex03_1 title="Gains for a damping ratio and a settling time"
def gains_for(zeta, t_settle):
    ### BEGIN SOLUTION
    rate = 4.0 / t_settle                     # the slow root is -rate
    if zeta <= 1.0:
        omega = rate / zeta                   # complex or double roots: real part -zeta omega
    else:
        omega = rate / (zeta - math.sqrt(zeta * zeta - 1.0))
    return 2.0 * zeta * omega, omega / (2.0 * zeta)
    ### END SOLUTION

# %% grade id=ex03_1_zeta_tests points=1
a1, b1 = gains_for(0.5, 4.0)
assert np.isclose(a1, 2.0) and np.isclose(b1, 2.0), \
    f"zeta = 0.5, t_settle = 4 s: expected (alpha, beta) = (2, 2); got ({a1!r}, {b1!r})"
a1, b1 = gains_for(1.0, 2.0)
assert np.isclose(a1, 4.0) and np.isclose(b1, 1.0), \
    f"zeta = 1, t_settle = 2 s: expected (alpha, beta) = (4, 1); got ({a1!r}, {b1!r})"
### BEGIN HIDDEN TESTS
def slow_root(a, b):
    """The tests' own roots: eigenvalues of the companion matrix of eq. (12)."""
    return np.linalg.eigvals(np.array([[0.0, 1.0], [-a * b, -a]])).real.max()


test_rng = np.random.default_rng(310)  # the tests' own draws, not the notebook's rng
for z, ts in zip(test_rng.uniform(0.05, 1.0, 100), test_rng.uniform(0.5, 20.0, 100)):
    a, b = gains_for(float(z), float(ts))
    assert np.isclose(0.5 * np.sqrt(a / b), z, rtol=1e-9), \
        f"zeta = {z:.4f}, t_settle = {ts:.3f}: your gains ({a:.6g}, {b:.6g}) have another zeta"
    assert np.isclose(slow_root(a, b), -4.0 / ts, rtol=1e-6), (
        f"zeta = {z:.4f}, t_settle = {ts:.3f}: expected the slowest root's real part "
        f"{-4.0 / ts:.6f}; got {slow_root(a, b):.6f}")
### END HIDDEN TESTS

# %% grade id=ex03_1_tests points=2
a1, b1 = gains_for(1.25, 2.0)
assert np.isclose(a1, 10.0) and np.isclose(b1, 1.6), \
    f"zeta = 1.25, t_settle = 2 s: expected (alpha, beta) = (10, 1.6); got ({a1!r}, {b1!r})"
### BEGIN HIDDEN TESTS
test_rng = np.random.default_rng(311)  # the tests' own draws, not the notebook's rng
for z, ts in zip(test_rng.uniform(1.0001, 8.0, 100), test_rng.uniform(0.5, 20.0, 100)):
    a, b = gains_for(float(z), float(ts))
    assert np.isclose(0.5 * np.sqrt(a / b), z, rtol=1e-9), \
        f"zeta = {z:.4f}, t_settle = {ts:.3f}: your gains ({a:.6g}, {b:.6g}) have another zeta"
    lam = np.roots([1.0, a, a * b]).real.max()     # the slow root, by np.roots
    assert np.isclose(lam, -4.0 / ts, rtol=1e-6), (
        f"zeta = {z:.4f}, t_settle = {ts:.3f}: expected the slowest root {-4.0 / ts:.6f}; "
        f"got {lam:.6f} (the fast root is not the one that sets the settling time)")
a, b = gains_for(1.0 + 1e-12, 2.0)
assert np.isclose(a, 4.0) and np.isclose(b, 1.0), \
    f"zeta = 1 + 1e-12, t_settle = 2 s: expected about (4, 1); got ({a!r}, {b!r})"
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 3.2 — an integrator the tutorial does not have: implicit Euler
# Explicit Euler evaluates the right-hand side of eq. (10) at the *old* state,
# semi-implicit Euler half at the new one. **Implicit (backward) Euler** evaluates
# all of it at the new state: with $a(y, \dot y) = \alpha(\beta(g - y) - \dot y)$,
#
# $$y' = y + h\,\dot y', \qquad \dot y' = \dot y + h\, a(y', \dot y').$$
#
# These are two equations for the two unknowns $y', \dot y'$. Solve them in closed
# form and write `implicit_euler_step(y, dy, goal, alpha, beta, h)` returning
# `(y_next, dy_next)`. It must work elementwise on NumPy arrays of any shape (no
# `np.linalg.solve`, no iteration).
#
# <details><summary>Hint 1 (the idea)</summary>
#
# The equations are linear in $y'$ and $\dot y'$: substitute the first into the second.
# </details>
#
# <details><summary>Hint 2 (the method)</summary>
#
# You get one equation for $\dot y'$ whose coefficient is a number built from $h$, α
# and β; divide by it. Then $y'$ follows from the first equation. Check your answer
# by putting it back into both equations.
# </details>

# %% solution id=ex03_2 title="Implicit Euler step"
def implicit_euler_step(y, dy, goal, alpha, beta, h):
    ### BEGIN SOLUTION
    det = 1.0 + h * alpha + h * h * alpha * beta
    dy_next = (dy + h * alpha * beta * (goal - y)) / det
    return y + h * dy_next, dy_next
    ### END SOLUTION

# %% grade id=ex03_2_tests points=3
y2, dy2 = implicit_euler_step(1.0, 0.0, 0.0, 4.0, 1.0, 0.5)
assert np.isclose(y2, 0.75) and np.isclose(dy2, -0.5), \
    f"y = 1, dy = 0, goal 0, alpha 4, beta 1, h 0.5: expected (0.75, -0.5); got ({y2!r}, {dy2!r})"
y2, dy2 = 1.0, 0.0
for _ in range(12):   # the textbook gains that explicit Euler blows up at h = 0.5
    y2, dy2 = implicit_euler_step(y2, dy2, 0.0, 25.0, 6.25, 0.5)
assert abs(y2) < 0.05, \
    f"alpha 25, beta 6.25, h 0.5, 12 steps from y = 1: expected |y| < 0.05; got {y2!r}"
### BEGIN HIDDEN TESTS
test_rng = np.random.default_rng(320)  # the tests' own draws, not the notebook's rng
y, dy, g = test_rng.normal(size=(3, 5, 2))
a, b = test_rng.uniform(0.5, 30, size=(2, 5, 1))
for h in (0.05, 0.5, 2.0):
    yn, dyn = implicit_euler_step(y, dy, g, a, b, h)
    assert np.shape(yn) == (5, 2) and np.shape(dyn) == (5, 2), \
        f"arrays (5, 2), h = {h}: expected shapes (5, 2); got {np.shape(yn)}, {np.shape(dyn)}"
    # the defining equations, evaluated at your new state
    np.testing.assert_allclose(yn, y + h * dyn, rtol=1e-10, atol=1e-12,
                               err_msg=f"arrays (5, 2), h = {h}: y' = y + h dy' must hold")
    np.testing.assert_allclose(dyn, dy + h * a * (b * (g - yn) - dyn), rtol=1e-10, atol=1e-12,
                               err_msg=f"arrays (5, 2), h = {h}: dy' = dy + h a(y', dy') must hold")
yn = implicit_euler_step(np.ones(3), 0.0, 0.0, 4.0, 1.0, 0.5)[0]
assert np.allclose(yn, 0.75), f"y = ones(3), scalar dy: expected 0.75 in every entry; got {yn}"
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 3.3 — the stable range of α for explicit Euler
# One explicit Euler step maps $[e, \dot e]$ by $M = I + hA$ with
# $A = \begin{pmatrix} 0 & 1 \\ -\alpha\beta & -\alpha \end{pmatrix}$, so its
# eigenvalues are $1 + h\lambda$ for the roots λ of eq. (12); the step is stable iff
# both lie strictly inside the unit circle. Derive for which α > 0 that holds and
# write `max_stable_alpha_euler(beta, h)`: the supremum of the stable α (stable
# exactly for 0 < α < that value), or `0.0` if no α > 0 is stable. The library's
# stability functions (`dmp.max_stable_alpha`, `dmp.spectral_radius`,
# `dmp.step_matrix`, `dmp.step_stable`) are switched off while this exercise is graded.
#
# <details><summary>Hint 1 (the idea)</summary>
#
# The roots λ are complex for small α and real for large α. Each regime gives one
# condition on α; ask in which regime the bound is reached.
# </details>
#
# <details><summary>Hint 2 (the method)</summary>
#
# For complex roots, $|1 + h\lambda|^2$ needs only the sum and the product of the two
# roots, which eq. (12) gives you. For real roots only the more negative one can
# leave the circle, and only through −1. Mind the case where the complex-root
# condition cannot hold for any α.
# </details>

# %% solution id=ex03_3 title="Stable range of alpha for explicit Euler" forbids="minimanc.dmp.max_stable_alpha,minimanc.dmp.spectral_radius,minimanc.dmp.step_matrix,minimanc.dmp.step_stable"  # noqa: E501
def max_stable_alpha_euler(beta, h):
    ### BEGIN SOLUTION
    if h * beta >= 1.0:
        return 0.0
    return 4.0 / (h * (2.0 - h * beta))
    ### END SOLUTION

# %% grade id=ex03_3_tests points=4
got = max_stable_alpha_euler(0.5, 0.5)
assert np.isclose(got, 4.571429), f"beta = 0.5, h = 0.5: expected 4.571429; got {got!r}"
got = max_stable_alpha_euler(1.0, 0.25)
assert np.isclose(got, 9.142857), f"beta = 1, h = 0.25: expected 9.142857; got {got!r}"
got = max_stable_alpha_euler(3.0, 0.5)
assert got == 0.0, f"beta = 3, h = 0.5: expected 0.0; got {got!r}"
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
for b, h in ((0.5, 0.5), (1.0, 0.25), (1.9, 0.5)):     # the bound against the step matrix
    a_max = max_stable_alpha_euler(b, h)
    for a, inside in ((0.99 * a_max, True), (1.01 * a_max, False)):
        M = np.eye(2) + h * np.array([[0.0, 1.0], [-a * b, -a]])
        rho = np.abs(np.linalg.eigvals(M)).max()
        assert (rho < 1) == inside, (
            f"beta={b}, h={h}: your bound {a_max!r}; alpha = {a:.4f} should be "
            f"{'stable' if inside else 'unstable'}, got rho = {rho:.4f}")
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 3.4 — the forcing-term weights by global least squares
# The tutorial (7.3) fits the forcing term by *locally* weighted regression: each
# weight $w_i$ on its own, as if its basis function were alone. But the DMP adds the
# **normalised** mixture $f(x) = \frac{\sum_i \psi_i(x) w_i}{\sum_i \psi_i(x)}\, x\,(g - y_0)$,
# so the weights act together. Fit them together: write
# `global_forcing_weights(demo, dt, alpha, beta, centres, widths, alpha_x)` returning
# the weights, shape `(n_basis, D)`, that minimise $\sum_k (f(x_k) - f_{target,k})^2$ for
# each dimension, with $f_{target}$ the tutorial's, $\psi_i(x) = e^{-\kappa_i (x - c_i)^2}$
# (`widths` are the $\kappa_i$), the phase $x_k = e^{-\alpha_x k\,\Delta t}$ (τ = 1),
# $y_0$ = `demo[0]`, $g$ = `demo[-1]`, and $\dot y, \ddot y$ by
# `np.gradient(..., dt, axis=0, edge_order=2)` applied twice (as the library does).
# `demo` has shape `(T + 1, D)`. The grade cell checks the fit by rolling the DMP
# out with your weights.
#
# <details><summary>Hint 1 (the idea)</summary>
#
# $f(x_k)$ is linear in the weights: for each dimension it is a matrix (one row per
# time step, one column per basis function) times the weight vector.
# </details>
#
# <details><summary>Hint 2 (the method)</summary>
#
# Write one entry of that matrix: what multiplies $w_i$ in $f(x_k)$? Once you have it,
# the fit is an ordinary least-squares problem, one per dimension. Check before rolling
# out: with the demonstration's own $f_{target}$, your residual must be no larger than the
# tutorial's local fit gives on the same samples.
# </details>

# %% solution id=ex03_4 title="Forcing-term weights by global least squares"
def global_forcing_weights(demo, dt, alpha, beta, centres, widths, alpha_x):
    ### BEGIN SOLUTION
    y = np.asarray(demo, dtype=float)
    dy = np.gradient(y, dt, axis=0, edge_order=2)
    ddy = np.gradient(dy, dt, axis=0, edge_order=2)
    g, y0 = y[-1], y[0]
    x = np.exp(-alpha_x * np.arange(len(y)) * dt)
    psi = np.exp(-widths * (x[:, None] - centres) ** 2)          # (T + 1, n)
    design = psi / psi.sum(axis=1, keepdims=True) * x[:, None]   # f = design @ w * (g - y0)
    f_target = ddy - alpha * (beta * (g - y) - dy)
    return np.stack([np.linalg.lstsq(design * (g - y0)[d], f_target[:, d], rcond=None)[0]
                     for d in range(y.shape[1])], axis=1)
    ### END SOLUTION

# %% grade id=ex03_4_tests points=3
t4 = np.arange(101) * 0.01
m4 = 10 * t4**3 - 15 * t4**4 + 6 * t4**5  # minimum jerk from 0 to 1 in 1 s
demo4 = np.stack([2 * m4, m4 + 0.8 * np.sin(np.pi * t4) ** 2], axis=-1)
ax4 = -np.log(0.01)  # the phase falls to 0.01 at t = 1 s
centres4, widths4 = dmp.basis_centres(10, ax4, 1.0)
w4 = global_forcing_weights(demo4, 0.01, 25.0, 6.25, centres4, widths4, ax4)
assert np.shape(w4) == (10, 2), \
    f"10 basis functions, D = 2: expected shape (10, 2) (n_basis, D), got {np.shape(w4)}"
r4 = dmp.rollout(demo4[0], np.zeros(2), demo4[-1], 25.0, 6.25, 0.01, 100,
                 forcing=dmp.Forcing(np.asarray(w4), centres4, widths4, ax4))
err4 = np.abs(r4.y - demo4).max()
assert err4 < 0.01, (f"the tutorial's swerving demo with 10 basis functions: expected the DMP "
                     f"to follow it within 1 cm; missed by {err4:.3f} m")
### BEGIN HIDDEN TESTS
# independent oracle: the normal equations of the same least-squares problem
x4 = np.exp(-ax4 * t4)
dy4 = np.gradient(demo4, 0.01, axis=0, edge_order=2)
f4 = np.gradient(dy4, 0.01, axis=0, edge_order=2) - 25.0 * (6.25 * (demo4[-1] - demo4) - dy4)
psi4 = np.exp(-widths4 * (x4[:, None] - centres4) ** 2)
for d in range(2):
    phi = psi4 / psi4.sum(axis=1, keepdims=True) * (x4 * (demo4[-1, d] - demo4[0, d]))[:, None]
    ref = np.linalg.solve(phi.T @ phi, phi.T @ f4[:, d])
    assert np.allclose(np.asarray(w4)[:, d], ref, rtol=1e-6, atol=1e-6 * np.abs(ref).max()), \
        (f"swerving demo, dimension {d}: expected w = {np.round(ref[:3], 3).tolist()}..., got "
         f"{np.round(np.asarray(w4)[:3, d], 3).tolist()}...")
# another demo, other gains, 1-D, a different duration (dt = 0.02, 2 s)
t5 = np.arange(101) * 0.02
demo5 = (1 - np.cos(np.pi * t5 / 2.0))[:, None] * 1.5  # from 0 to 3, at rest at both ends
ax5 = -np.log(0.01) / 2.0  # x(2 s) = 0.01
centres5, widths5 = dmp.basis_centres(20, ax5, 2.0)
w5 = global_forcing_weights(demo5, 0.02, 10.0, 2.5, centres5, widths5, ax5)
r5 = dmp.rollout(demo5[0], np.zeros(1), demo5[-1], 10.0, 2.5, 0.02, 100,
                 forcing=dmp.Forcing(np.asarray(w5), centres5, widths5, ax5))
err5 = np.abs(r5.y - demo5).max()
assert err5 < 0.01, \
    f"a cosine reach from 0 to 3 m, dt = 0.02: expected within 1 cm, missed by {err5:.3f} m"
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 3.5 — the stable range of α for semi-implicit Euler
# The package integrates with semi-implicit Euler: velocity first, then the position
# with the *new* velocity (tutorial section 3). One sub-step of `h` is a linear map
# $M$ of $[e, \dot e]$; derive it. Jury's conditions say both eigenvalues of a real
# 2×2 matrix lie strictly inside the unit circle iff $|\det M| < 1$,
# $1 - \mathrm{tr}\,M + \det M > 0$ and $1 + \mathrm{tr}\,M + \det M > 0$. Work them out
# for α, β > 0 and write `max_stable_alpha_semi_implicit(beta, h)`: the supremum of
# the stable α (stable exactly for 0 < α < that value). The library's stability
# functions are switched off while this exercise is graded.
#
# <details><summary>Hint 1 (the idea)</summary>
#
# Write one sub-step as two lines, $\dot e' = \dots$ and $e' = e + h\,\dot e'$, and
# substitute the first into the second: the columns of $M$ follow. Each Jury
# condition is then an inequality in α for fixed β and h.
# </details>
#
# <details><summary>Hint 2 (the method)</summary>
#
# The determinant and trace are short. One condition always holds, one bounds
# $h\alpha$ alone, and one gives the answer; check which of the last two binds.
# </details>

# %% solution id=ex03_5 title="Stable range of alpha for semi-implicit Euler" forbids="minimanc.dmp.max_stable_alpha,minimanc.dmp.spectral_radius,minimanc.dmp.step_matrix,minimanc.dmp.step_stable"  # noqa: E501
def max_stable_alpha_semi_implicit(beta, h):
    ### BEGIN SOLUTION
    # det M = 1 - h alpha, tr M = 2 - h alpha - h^2 alpha beta
    # 1 - tr + det = h^2 alpha beta > 0 always; |det| < 1 <=> 0 < h alpha < 2;
    # 1 + tr + det = 4 - h alpha (2 + h beta) > 0 <=> alpha < 4 / (h (2 + h beta)) <= 2/h
    return 4.0 / (h * (2.0 + h * beta))
    ### END SOLUTION

# %% grade id=ex03_5_tests points=3
got = max_stable_alpha_semi_implicit(1.0, 0.5)
assert np.isclose(got, 3.2), f"beta = 1, h = 0.5: expected 3.2; got {got!r}"
got = max_stable_alpha_semi_implicit(5.0, 0.05)
assert np.isclose(got, 35.555556), \
    f"the package's corner beta = 5 at h = 0.05: expected 35.555556; got {got!r}"
got = max_stable_alpha_semi_implicit(0.1, 0.25)
assert np.isclose(got, 7.901235), f"beta = 0.1, h = 0.25: expected 7.901235; got {got!r}"
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
# ## Exercise 3.7 — an open experiment: defend a gain box for one sub-step at dt = 0.5 s
# The library keeps the learned gains inside a box (`dmp.ALPHA_RANGE`,
# `dmp.BETA_RANGE`) and integrates with several sub-steps. Suppose the controller
# may take **one** sub-step of $h = 0.5$ s. Design the box yourself:
# `gain_box()` returns `(method, (alpha_lo, alpha_hi), (beta_lo, beta_hi))` with
# `method` one of `"euler"`, `"semi_implicit"`, `"rk2"` (Heun, 3.6), such that
#
# * every gain pair of the box (edges and corners included) is stable for one
#   step of `method` with $h = 0.5$;
# * the box holds a critically damped pair ($\alpha = 4\beta$ for some $\beta$ in it);
# * its area $(\alpha_\text{hi} - \alpha_\text{lo})(\beta_\text{hi} - \beta_\text{lo})$ is at
#   least 4 (in 1/s²), with $\alpha_\text{lo}, \beta_\text{lo} > 0$.
#
# Use your own bounds of 3.3, 3.5 and 3.6 to choose (3 points; the grade cell
# steps the corners of your box and checks the whole box). Then defend your choice
# in the written answer below.

# %% solution id=ex03_7 title="A stable gain box for one sub-step"
def gain_box():
    ### BEGIN SOLUTION
    betas = np.linspace(0.1, 4.0, 40)
    # the RK2 bound over the box's beta range; stay 2 % inside its lowest point
    alpha_hi = 0.98 * min(max_stable_alpha_rk2(float(b), 0.5) for b in betas)
    return "rk2", (0.1, float(alpha_hi)), (0.1, 4.0)
    ### END SOLUTION

# %% grade id=ex03_7_tests points=3
box7 = gain_box()
assert isinstance(box7, tuple) and len(box7) == 3, \
    f"expected (method, (alpha_lo, alpha_hi), (beta_lo, beta_hi)), got {box7!r}"
method7, (a_lo, a_hi), (b_lo, b_hi) = box7
assert method7 in ("euler", "semi_implicit", "rk2"), \
    f"expected 'euler', 'semi_implicit' or 'rk2', got {method7!r}"
assert 0 < a_lo < a_hi and 0 < b_lo < b_hi, \
    f"expected 0 < lo < hi for both gains, got alpha {(a_lo, a_hi)}, beta {(b_lo, b_hi)}"
area7 = (a_hi - a_lo) * (b_hi - b_lo)
assert area7 >= 4, f"expected an area of at least 4, got {area7:.3f}"
assert 4 * b_lo <= a_hi and a_lo <= 4 * b_hi, (
    f"alpha {(a_lo, a_hi)}, beta {(b_lo, b_hi)}: expected a pair with alpha = 4 beta, got none")
for a7, b7 in ((a_lo, b_lo), (a_lo, b_hi), (a_hi, b_lo), (a_hi, b_hi)):
    e7, v7 = 1.0, 0.0
    for _ in range(400):   # 400 steps of 0.5 s from the error 1, by the method's definition
        if method7 == "euler":
            e7, v7 = e7 + 0.5 * v7, v7 + 0.5 * (-a7 * b7 * e7 - a7 * v7)
        elif method7 == "semi_implicit":
            v7 = v7 + 0.5 * (-a7 * b7 * e7 - a7 * v7)
            e7 = e7 + 0.5 * v7
        else:
            k1 = (v7, -a7 * b7 * e7 - a7 * v7)
            k2 = (v7 + 0.5 * k1[1], -a7 * b7 * (e7 + 0.5 * k1[0]) - a7 * (v7 + 0.5 * k1[1]))
            e7, v7 = e7 + 0.25 * (k1[0] + k2[0]), v7 + 0.25 * (k1[1] + k2[1])
    assert abs(e7) < 1e-3, (f"{method7}, h = 0.5, the corner alpha = {a7:.3f}, beta = {b7:.3f}: "
                            f"expected the error to die out in 400 steps; it is {abs(e7):.3g}")
### BEGIN HIDDEN TESTS
def step_matrix7(a, b, h, method):
    """The tests' own one-step matrices on the state (e, de/dt)."""
    hA = h * np.array([[0.0, 1.0], [-a * b, -a]])
    if method == "euler":
        return np.eye(2) + hA
    if method == "rk2":
        return np.eye(2) + hA + 0.5 * hA @ hA
    return np.array([[1.0 - h * h * a * b, h * (1.0 - h * a)], [-h * a * b, 1.0 - h * a]])


worst7 = max((np.abs(np.linalg.eigvals(step_matrix7(a, b, 0.5, method7))).max(), a, b)
             for a in np.linspace(a_lo, a_hi, 25) for b in np.linspace(b_lo, b_hi, 25))
assert worst7[0] < 1, (f"{method7}, h = 0.5: expected every pair stable, got a spectral radius "
                       f"{worst7[0]:.4f} at alpha = {worst7[1]:.3f}, beta = {worst7[2]:.3f}")
test_rng = np.random.default_rng(370)  # the tests' own draws, not the notebook's rng
for a, b in zip(test_rng.uniform(a_lo, a_hi, 400), test_rng.uniform(b_lo, b_hi, 400)):
    rho7 = np.abs(np.linalg.eigvals(step_matrix7(a, b, 0.5, method7))).max()
    assert rho7 < 1, (f"{method7}, h = 0.5, alpha = {a:.4f}, beta = {b:.4f}: expected a "
                      f"spectral radius < 1, got {rho7:.4f}")
### END HIDDEN TESTS

# %% [markdown]
# **Written question (graded by hand, 2 points).** Defend your box: why this
# integrator, and what limits each edge of the box? What would explicit Euler's
# best box lose, and why do the Euler and RK2 bounds coincide while $h\beta < 1$?

# %% [markdown] answer id=ex03_w title="Defend the gain box" points=2
# ### BEGIN SOLUTION
# RK2 (Heun): one sub-step of $h = 0.5$ s costs two evaluations but keeps a stable α
# range for every β, where explicit Euler has none once $h\beta \ge 1$ (β ≥ 2 here)
# and semi-implicit Euler's bound $4/(h(2 + h\beta))$ is below 3 from β ≈ 1.3 on.
# The upper α edge is the lowest RK2 bound over the β range (it falls with β once
# hβ > 1, so it is set at β_hi = 4: 4.0, kept 2 % inside: 3.92); the lower edges only keep
# the gains positive (α, β > 0 is the continuous system's condition); β_hi trades area
# against α_hi. Euler's best box stops at β < 2 and loses everything with β ≥ 2. For
# $h\beta < 1$ both lose stability the same way: the eigenvalues of $hA$ are real and
# one reaches $z = -2$, where $1 + z = -1$ and $1 + z + z^2/2 = 1$, so both step
# polynomials have modulus 1 at the same α; only RK2 stays stable when the roots are
# complex ($h\beta \ge 1$), where Euler's $|1 + z| < 1$ fails.
# ### END SOLUTION

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
