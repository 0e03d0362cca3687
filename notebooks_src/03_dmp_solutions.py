# %% [markdown]
# # Chapter 3 — Graded exercises: DMP damping and step stability
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
import numpy as np

from minimanc import dmp

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

# %% grade id=ex03_1_tests points=3
assert np.isclose(damping_ratio(4.0, 1.0), 1.0)
assert np.isclose(damping_ratio(1.0, 1.0), 0.5)
assert classify(4.0, 1.0) == "critically damped"
assert classify(1.0, 1.0) == "underdamped"
assert classify(16.0, 1.0) == "overdamped"
assert classify(-1.0, 1.0) == "unstable"
### BEGIN HIDDEN TESTS
for a, b in rng.uniform(0.01, 50, size=(200, 2)):
    assert np.isclose(damping_ratio(a, b), 0.5 * np.sqrt(a / b))
    assert classify(a, b) == ("underdamped" if a < 4 * b else "overdamped"), (a, b)
for a in rng.uniform(0.1, 50, size=20):
    assert classify(a, a / 4) == "critically damped"
for b in (0.25, 1.0, 6.25, 40.0):   # zeta = 1 + d: alpha = 4 beta (1 + d)^2
    for d in (1e-12, -1e-12, 1e-10, -1e-10):
        assert classify(4 * b * (1 + d) ** 2, b) == "critically damped", f"zeta = 1 + {d:g}"
    assert classify(4 * b * (1 + 1e-8) ** 2, b) == "overdamped", "zeta = 1 + 1e-08"
    assert classify(4 * b * (1 - 1e-8) ** 2, b) == "underdamped", "zeta = 1 - 1e-08"
assert classify(1.0, 0.0) == "unstable" and classify(0.0, 1.0) == "unstable"
assert classify(1.0, -3.0) == "unstable"
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
assert np.isclose(y1, 1.0) and np.isclose(dy1, -2.0)
y1, dy1 = integrator_step(1.0, 0.0, 0.0, 4.0, 1.0, 0.5, "semi_implicit")
assert np.isclose(y1, 0.0) and np.isclose(dy1, -2.0)
try:
    integrator_step(1.0, 0.0, 0.0, 4.0, 1.0, 0.5, "leapfrog")
    raise AssertionError("an unknown method must raise ValueError")
except ValueError:
    pass
### BEGIN HIDDEN TESTS
for method in ("euler", "semi_implicit"):
    y, dy, g = rng.normal(size=(3, 5, 2))
    a, b = rng.uniform(0.5, 10, size=(2, 5, 1))
    yn, dyn = integrator_step(y, dy, g, a, b, 0.1, method)
    ref_dy = dy + 0.1 * a * (b * (g - y) - dy)
    ref_y = y + 0.1 * (dy if method == "euler" else ref_dy)
    assert yn.shape == (5, 2)
    assert np.allclose(yn, ref_y) and np.allclose(dyn, ref_dy)
assert np.allclose(integrator_step(np.ones(3), 0.0, 0.0, 4.0, 1.0, 0.5, "euler")[1], -2.0)
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
assert np.isclose(max_stable_alpha_euler(0.5, 0.5), 32 / 7)
assert max_stable_alpha_euler(3.0, 0.5) == 0.0
a_max = max_stable_alpha_euler(1.0, 0.25)
assert dmp.spectral_radius(0.99 * a_max, 1.0, 0.25, "euler", 1) < 1
assert dmp.spectral_radius(1.01 * a_max, 1.0, 0.25, "euler", 1) > 1
### BEGIN HIDDEN TESTS
for b in rng.uniform(0.05, 5, size=30):
    for h in (0.05, 0.25, 0.5):
        expected = 0.0 if h * b >= 1 else 4.0 / (h * (2.0 - h * b))
        assert np.isclose(max_stable_alpha_euler(b, h), expected), (b, h)
for h, b in ((0.5, 2.0), (0.25, 4.0), (0.125, 8.0)):   # h*beta = 1 exactly: marginal
    assert max_stable_alpha_euler(b, h) == 0.0, "h*beta = 1: no alpha > 0 is stable"
assert np.isclose(max_stable_alpha_euler(1.5, 0.5), 6.4)   # h*beta = 0.75
assert np.isclose(max_stable_alpha_euler(1e-6, 0.5), 4.0 / (0.5 * (2.0 - 5e-7)))
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
