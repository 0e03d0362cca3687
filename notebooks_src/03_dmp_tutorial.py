# %% [markdown]
# # Chapter 3 — Dynamic movement primitives: damping, step stability, forcing term
#
# Module built in this chapter: **`minimanc.dmp`** (point attractor, damping
# ratio, stability of the discrete step, rollouts, learned gains, and the full
# DMP of eq. 1 with its canonical system and forcing term).
#
# The motion controller of MANC is a *dynamic movement primitive* (DMP). The
# classical DMP (paper, eq. 1) is a spring–damper pulled towards a goal $g$,
# plus a learned forcing term $f$:
#
# $$\tau \ddot y = \alpha\,(\beta\,(g - y) - \dot y) + f(s, x).$$
#
# Here $x$ is the phase of the *canonical system* $\tau\dot x = -\alpha_x x$
# (the paper prints $\tau\dot x = \alpha_x x$, a sign slip: the phase must
# decay). The paper drops $f$ — a forcing term that never fades could fight the
# attractor on an endless drive; section 7 builds $f$ and *shows* it — and lets
# the network choose the gains instead (eq. 10):
#
# $$\ddot y = \alpha(s)\,\big(\beta(s)\,(g - y) - \dot y\big).$$
#
# With the error $e = y - g$ this is the textbook second-order system of eq. (12),
# $\ddot e + \alpha \dot e + \alpha\beta\, e = 0$, with natural frequency
# $\omega_n = \sqrt{\alpha\beta}$ and damping ratio (eq. 13)
#
# $$\zeta = \frac{\alpha}{2\sqrt{\alpha\beta}} = \tfrac12\sqrt{\alpha/\beta}.$$
#
# This chapter answers three questions a learned controller must face:
# how do α and β shape the motion; when does the *continuous* system converge;
# and when does the *discrete* step we actually compute (at the data rate,
# $\Delta t = 0.5$ s) converge — which is a different question.
#
# **Objectives.** After this chapter you can
# - read the damping ratio and the convergence of the DMP's point attractor (eqs. 10–13)
# - decide when a discrete integrator step is stable (its spectral radius) and bound the
#   gains
# - fit a forcing term by locally weighted regression
#
# **Prerequisites.** Chapter 1; linear second-order ODEs and the eigenvalues of a 2×2
# matrix.
#
# **Time.** About 60 minutes for the tutorial and 150 for the exercises.

# %%
import warnings

import matplotlib.pyplot as plt
import numpy as np

from minimanc import dmp, engine

rng = np.random.default_rng(0)
print(f"package step DT = {dmp.DT} s, default integrator: {dmp.DEFAULT_METHOD} "
      f"with {dmp.DEFAULT_SUBSTEPS} sub-steps")

# %% [markdown]
# ## 1. Under-, critically and over-damped
# Fix β = 1 and vary α. The characteristic roots of eq. (12) are
# $\lambda = \tfrac12\left(-\alpha \pm \sqrt{\alpha^2 - 4\alpha\beta}\right)$:
# complex when ζ < 1 (the error oscillates while it decays), a double root at
# ζ = 1 (β = α/4, the fastest approach without overshoot), two real roots when
# ζ > 1 (sluggish). We integrate with RK4 and many sub-steps, so what we see
# is the continuous system.

# %%
cases = [(1.0, 1.0), (4.0, 1.0), (16.0, 1.0)]  # (α, β): ζ = 0.5, 1, 2
T, dt = 24, 0.5
t = np.arange(T + 1) * dt
fig, ax = plt.subplots(figsize=(8, 3.5))
overshoot = {}
for alpha, beta in cases:
    r = dmp.rollout(np.array([0.0]), np.array([0.0]), 1.0, alpha, beta, dt, T,
                    method="rk4", substeps=20)
    zeta = dmp.damping_ratio(alpha, beta)
    kind = dmp.classify(alpha, beta)
    overshoot[kind] = r.y[:, 0].max() - 1.0
    lam = dmp.eigenvalues(alpha, beta)
    print(f"alpha={alpha:5.1f} beta={beta:.1f}  zeta={zeta:.2f}  {kind:17s} "
          f"roots={np.round(lam, 3)}  overshoot={max(overshoot[kind], 0):.3f}")
    ax.plot(t, r.y[:, 0], marker=".", label=f"ζ = {zeta:.1f} ({kind})")
ax.axhline(1.0, color="k", lw=0.8, ls="--")
ax.set_xlabel("t (s)")
ax.set_ylabel("y")
ax.set_title("Step response towards g = 1 from rest")
ax.legend()
plt.show()
assert overshoot["underdamped"] > 0.1
assert overshoot["critically damped"] <= 1e-9 and overshoot["overdamped"] <= 1e-9

# %% [markdown]
# ## 2. Phase portraits
# In the plane $(e, \dot e)$ every trajectory flows to the origin. Underdamped
# systems spiral in; critically and over-damped ones slide in along the real
# eigenvectors (the straight lines $\dot e = \lambda e$).

# %%
fig, axes = plt.subplots(1, 3, figsize=(12, 3.8), sharex=True, sharey=True)
angles = np.linspace(0, 2 * np.pi, 9)[:-1]
e0, v0 = 2 * np.cos(angles)[:, None], 4 * np.sin(angles)[:, None]  # a batch of 8 starts
for ax, (alpha, beta) in zip(axes, cases):
    r = dmp.rollout(e0, v0, 0.0, alpha, beta, 0.02, 750, method="rk4", substeps=1)
    ax.plot(r.y[:, :, 0], r.dy[:, :, 0], lw=1)
    ax.plot(e0, v0, "k.", ms=4)
    assert np.all(np.hypot(r.y[-1], r.dy[-1]) < 0.02)  # every start reaches the goal at rest
    lam = dmp.eigenvalues(alpha, beta)
    for l in lam[np.abs(lam.imag) < 1e-12].real:  # real eigen-directions
        ax.plot([-3, 3], [-3 * l, 3 * l], "k--", lw=0.7)
    ax.set_title(f"α = {alpha:g}, β = {beta:g}: ζ = {dmp.damping_ratio(alpha, beta):.1f}")
    ax.set_xlim(-3, 3)
    ax.set_ylim(-6, 6)
    ax.set_xlabel("e = y − g")
axes[0].set_ylabel("ė")
plt.show()


# %% [markdown]
# ## 3. The step we actually compute
# The controller runs at the data rate, $\Delta t = 0.5$ s. Each integrator
# turns the ODE into a linear map of the state $[e, \dot e]$; with
# $h = \Delta t / \text{substeps}$:
#
# * **explicit Euler**: $e \leftarrow e + h\dot e$, $\dot e \leftarrow \dot e + h\,\ddot e$;
# * **semi-implicit (symplectic) Euler**: velocity first, then position with the *new*
#   velocity — the usual DMP update;
# * **RK4**.
#
# The discrete system converges iff the spectral radius ρ of the one-step
# matrix is below 1. `dmp.step_matrix` returns that matrix; `dmp.spectral_radius` its ρ.
# The textbook gains (movement_primitives: α = 25, β = α/4, meant for
# $\Delta t = 0.01$) are critically damped — yet at 0.5 s the explicit Euler step
# matrix has the double eigenvalue $1 - h\alpha/2 = -5.25$, so its spectral radius
# is 5.25. That does not mean "each step multiplies the error by −5.25": at a
# double root the step matrix is a Jordan block (not diagonalisable), and after
# $k$ steps the error grows like $k \cdot 5.25^k$.

# %%
a_tb, b_tb = 25.0, 25.0 / 4
print(f"zeta = {dmp.damping_ratio(a_tb, b_tb):.2f} ({dmp.classify(a_tb, b_tb)})")
print("one-step matrix, explicit Euler, dt = 0.5:")
print(np.round(dmp.step_matrix(a_tb, b_tb, 0.5, "euler", 1), 3))
for method, n in [("euler", 1), ("semi_implicit", 1), ("rk4", 1), ("euler", 4),
                  ("semi_implicit", 10)]:
    rho = dmp.spectral_radius(a_tb, b_tb, 0.5, method, n)
    print(f"{method:14s} substeps={n:2d}: spectral radius {rho:8.3f}  "
          f"{'stable' if rho < 1 else 'DIVERGES'}")
assert np.isclose(dmp.spectral_radius(a_tb, b_tb, 0.5, "euler", 1), 5.25)
M_tb = dmp.step_matrix(a_tb, b_tb, 0.5, "euler", 1)
assert not np.allclose(M_tb, -5.25 * np.eye(2))  # a Jordan block, not −5.25 · I
growth = [np.abs(np.linalg.matrix_power(M_tb, k)).max() / (k * 5.25**k) for k in (10, 20, 40)]
assert np.allclose(growth, growth[-1], rtol=0.15)  # ‖M^k‖ ∝ k · 5.25^k

# %% [markdown]
# `dmp.step` and `dmp.rollout` run this same analysis once per call (on
# concrete gains; never inside `grad`/`jit`) and refuse a step whose spectral
# radius exceeds 1, stating ρ and the stable range of α:

# %% tags=["raises-exception"]
dmp.rollout(np.array([1.0]), np.array([0.0]), 0.0, a_tb, b_tb, 0.5, 8, "euler", 1)

# %% [markdown]
# To *show* the divergence anyway, opt in with `allow_unstable=True`: the
# rollout runs and emits one `RuntimeWarning` (caught here, so that we can
# assert on it).

# %%
fig, ax = plt.subplots(figsize=(8, 3.2))
for method, n in [("euler", 1), ("euler", 4), ("semi_implicit", 10)]:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        r = dmp.rollout(np.array([1.0]), np.array([0.0]), 0.0, a_tb, b_tb, 0.5, 8, method, n,
                        allow_unstable=True)
    unstable = [w for w in caught if issubclass(w.category, RuntimeWarning)]
    assert len(unstable) == (not dmp.step_stable(a_tb, b_tb, 0.5, method, n))
    print(f"{method:14s} substeps={n:2d}: "
          f"{'RuntimeWarning: unstable, run anyway' if unstable else 'stable, no warning'}")
    ax.semilogy(np.arange(9) * 0.5, np.abs(r.y[:, 0]) + 1e-16, marker="o",
                label=f"{method}, {n} sub-step(s)")
ax.set_xlabel("t (s)")
ax.set_ylabel("|y − g|")
ax.set_title("α = 25, β = α/4 stepped at 0.5 s")
ax.legend()
plt.show()

# %% [markdown]
# ### A stability map over (α, β)
# For α, β > 0 the continuous system always converges (left panel: only its
# *character* changes, across the line β = α/4). The discrete step is another
# matter: for each integrator and step there is a largest stable α for each β.
# For the two Euler schemes it has a closed form, which you derive in the
# exercises: for explicit Euler through the eigenvalues $1 + h\lambda$ of the
# step (exercise 3.3), for semi-implicit Euler through Jury's conditions on the
# determinant and trace of its 2×2 step matrix (exercise 3.5). RK4's is found
# numerically. `dmp.max_stable_alpha` returns these bounds; the dashed curves
# below are drawn from it, the colours from the spectral radius.

# %%
A, B = np.meshgrid(np.linspace(0.1, 30, 240), np.linspace(0.05, 6, 200))
kinds = dmp.classify(A, B)
code = np.select([kinds == "underdamped", kinds == "overdamped"], [0, 2], 1)
panels = [("euler", 1), ("semi_implicit", 1), ("rk4", 1),
          (dmp.DEFAULT_METHOD, dmp.DEFAULT_SUBSTEPS)]
fig, axes = plt.subplots(2, 3, figsize=(14, 7.5), layout="constrained")
axes = axes.ravel()
axes[0].contourf(A, B, code, levels=[-0.5, 0.5, 1.5, 2.5], colors=["#9ecae1", "k", "#fdae6b"])
axes[0].plot(A[0], A[0] / 4, "k", lw=1)
axes[0].set_ylim(B.min(), B.max())
axes[0].set_title("continuous: underdamped (blue), overdamped (orange)", fontsize=10)
for ax, (method, n) in zip(axes[1:5], panels):
    rho = dmp.spectral_radius(A, B, 0.5, method, n)
    cs = ax.contourf(A, B, np.log10(rho), levels=np.linspace(-2, 2, 21), cmap="RdBu_r",
                     extend="both")
    betas = B[:, 0]
    bound = np.array([dmp.max_stable_alpha(b, 0.5, method, n) for b in betas])
    ax.plot(np.where(bound < 30, bound, np.nan), betas, "k--", lw=1.5)
    # the closed form matches the map: stable exactly left of the curve (away from it)
    margin = np.abs(A - bound[:, None]) > 0.2
    assert np.array_equal((rho < 1)[margin], (A < bound[:, None])[margin])
    frac = (rho < 1).mean()
    ax.set_title(f"{method}, {n} sub-step(s): {100 * frac:.0f}% stable", fontsize=10)
    print(f"{method:14s} substeps={n:2d}: {100 * frac:5.1f}% of the map is stable at dt = 0.5")
fig.colorbar(cs, ax=axes[2], label="log10 spectral radius")
axes[4].add_patch(plt.Rectangle((dmp.ALPHA_RANGE[0], dmp.BETA_RANGE[0]),
                                np.diff(dmp.ALPHA_RANGE)[0], np.diff(dmp.BETA_RANGE)[0],
                                fill=False, ec="lime", lw=2))
for ax in axes[:5]:
    ax.set_xlabel("α")
    ax.set_ylabel("β")
alphas = np.linspace(0.1, 30, 600)
for method, n in panels:
    axes[5].semilogy(alphas, dmp.spectral_radius(alphas, 1.0, 0.5, method, n),
                     label=f"{method}, {n}")
axes[5].axhline(1.0, color="k", lw=0.8)
axes[5].set_xlabel("α (β = 1)")
axes[5].set_ylabel("spectral radius")
axes[5].legend(fontsize=8)
plt.show()

# %% [markdown]
# Red is unstable (ρ > 1), blue stable. The right panel is the package
# default (semi-implicit Euler, 10 sub-steps of 0.05 s) with the box in which
# learned gains live (green); `tests/test_dmp.py` proves that the whole box is
# stable. Two different questions hide here, and they have different worst
# corners:
#
# * **Stability margin — the corner (α_max, β_max) = (20, 5).** The largest
#   stable α falls as β grows (dashed curve in the right panel above), so the
#   box is closest to the stability boundary at its top-right corner: the cell
#   below prints how far α may grow there before the step diverges.
# * **Slowest convergence — the corner (α_max, β_min) = (20, 0.05).** The
#   spectral radius says how fast a stable step forgets the error. With α ≫ β the
#   slow root of eq. (12) is λ ≈ −β: the error closes at rate β, so per step it
#   shrinks only by about $e^{-\beta\,\Delta t} \approx 0.975$. That ρ is close to 1
#   because the motion is sluggish, not because the step is near divergence.

# %%
for b in dmp.BETA_RANGE:
    print(f"beta = {b:4.2f}: stable for alpha < {dmp.max_stable_alpha(b):6.2f} "
          f"(box goes to {dmp.ALPHA_RANGE[1]:.0f})")
a_hi, b_hi = dmp.ALPHA_RANGE[1], dmp.BETA_RANGE[1]
a_grid, b_grid = np.meshgrid(np.linspace(*dmp.ALPHA_RANGE, 100), np.linspace(*dmp.BETA_RANGE, 100))
rho_box = dmp.spectral_radius(a_grid, b_grid)
bound_box = np.array([dmp.max_stable_alpha(b) for b in b_grid[:, 0]])[:, None]
margins = bound_box - a_grid  # how far alpha may still grow before the step diverges
margin = margins[-1, -1]
print(f"stability margin: alpha may grow by at least {margins.min():.2f} before the step "
      f"diverges, least at the corner alpha={a_hi:.0f}, beta={b_hi:.0f}")
assert margins.min() == margin > 0  # the margin is smallest at (20, 5)
print(f"slowest convergence: largest spectral radius {rho_box.max():.3f} "
      f"at alpha={a_grid.flat[rho_box.argmax()]:.0f}, beta={b_grid.flat[rho_box.argmax()]:.2f} "
      f"(about exp(-beta*DT) = {np.exp(-dmp.BETA_RANGE[0] * dmp.DT):.3f})")
print(f"at the margin corner (20, 5) the spectral radius is only "
      f"{dmp.spectral_radius(a_hi, b_hi):.3f}: close to the boundary, yet fast")
assert rho_box.max() < 1 and np.isclose(rho_box.max(), dmp.spectral_radius(20.0, 0.05))

# %% [markdown]
# ## 4. Learned gains: why the sigmoid keeps ζ > 0
# The paper outputs α and β through a sigmoid. Both are then positive, so
# ζ = ½√(α/β) > 0: the continuous system is never unstable. But ζ can still
# approach 0 — an oscillating controller — whenever β ≫ α, and a sigmoid into
# (0, 1) also allows α → 0 (no damping at all, no motion). `gains_from_logits`
# maps logits into the box above, which bounds ζ from below by
# ½√(α_min/β_max) ≈ 0.16; the paper's two remedies are also here: the
# `critically_damped=True` option (β = α/4, ζ = 1) and `zeta_penalty`, an
# auxiliary loss $\max(\zeta_{min} - \zeta, 0)^2$.

# %%
z = rng.normal(scale=2.0, size=(2, 20000))
sig = 1 / (1 + np.exp(-z))
zeta_raw = dmp.damping_ratio(sig[0], sig[1])  # the bare sigmoid: α, β ∈ (0, 1)
a_box, b_box = dmp.gains_from_logits(z[0], z[1])
zeta_box = dmp.damping_ratio(a_box, b_box)
fig, axes = plt.subplots(1, 2, figsize=(11, 3.4))
bins = np.logspace(-2, 1.5, 60)
axes[0].hist(zeta_raw, bins=bins, alpha=0.6, label="sigmoid into (0, 1)")
axes[0].hist(zeta_box, bins=bins, alpha=0.6, label="gains_from_logits box")
axes[0].axvline(1, color="k", lw=0.8)
axes[0].set_xscale("log")
axes[0].set_xlabel("ζ")
axes[0].legend()
zs = np.linspace(0.01, 1.5, 200)
alpha_for = 4 * zs**2  # ζ = ½ √(α / 1): α = 4 ζ²
axes[1].plot(zs, [dmp.zeta_penalty(a, 1.0, zeta_min=0.5) for a in alpha_for])
axes[1].set_xlabel("ζ")
axes[1].set_ylabel("zeta_penalty (ζ_min = 0.5)")
plt.show()
print(f"bare sigmoid: min zeta {zeta_raw.min():.4f}, {100 * (zeta_raw < 0.1).mean():.1f}% "
      f"below 0.1")
print(f"package box : min zeta {zeta_box.min():.4f} "
      f"(bound {0.5 * np.sqrt(dmp.ALPHA_RANGE[0] / dmp.BETA_RANGE[1]):.4f})")
assert zeta_box.min() >= 0.5 * np.sqrt(dmp.ALPHA_RANGE[0] / dmp.BETA_RANGE[1]) - 1e-12
assert np.all(zeta_raw > 0)

# %% [markdown]
# ## 5. Time-varying gains and a moving goal
# In MANC the goal is a lane point ahead of the car, moving as the car moves,
# and the gains change every step as the vAGN changes state. `rollout` accepts
# both as arrays over time (`per_step=("goal", "alpha", "beta")`). Below, a 2-D
# point follows a target that moves along a curve at 6 m/s; at t = 10 s the
# "planner" switches from cautious gains to brisk ones. A goal moving at speed
# c is followed at speed c with a lag that stays behind it; the brisk gains close up
# on the target (how the lag depends on the gains is exercise 4.7's question).

# %%
T = 40
tt = np.arange(1, T + 1) * dmp.DT
goal = np.stack([6.0 * tt, 20 * np.sin(tt / 6)], axis=-1)           # (T, 2)
alpha_t = np.where(tt <= 10, 2.0, 8.0)[:, None]                      # (T, 1)
beta_t = np.where(tt <= 10, 0.3, 1.5)[:, None]
r = dmp.rollout(np.array([0.0, -5.0]), np.zeros(2), goal, alpha_t, beta_t, dmp.DT, T,
                per_step=("goal", "alpha", "beta"))
gap = np.linalg.norm(goal - r.y[1:], axis=-1)
fig, axes = plt.subplots(1, 2, figsize=(12, 3.6))
axes[0].plot(goal[:, 0], goal[:, 1], "k.", ms=4, label="moving goal")
axes[0].plot(r.y[:, 0], r.y[:, 1], "-o", ms=3, label="DMP")
axes[0].set_xlabel("x (m)")
axes[0].set_ylabel("y (m)")
axes[0].legend()
axes[1].plot(tt, gap, label="distance to goal (m)")
axes[1].plot(tt, np.linalg.norm(r.dy[1:], axis=-1), label="speed (m/s)")
axes[1].axvline(10, color="k", lw=0.8, ls="--")
axes[1].set_xlabel("t (s)")
axes[1].legend()
plt.show()
print(f"gap before the switch {gap[tt <= 10][-1]:.2f} m, at the end {gap[-1]:.2f} m")
assert gap[-1] < 0.5 * gap[tt <= 10][-1]

# %% [markdown]
# ## 6. Training through a rollout
# Behaviour cloning (chapter 9) differentiates the controls through the DMP.
# Here is the smallest version: a demonstration (10 velocities) made with
# unknown gains, and Adam on the two logits through a 10-step rollout, with our
# NumPy autodiff engine (`engine("jax")` gives the same gradients). The loss
# landscape on the left is one *batched* rollout: 1600 gain pairs at once. (60 Adam
# steps: the fitted gains are checked by the assert, to 3 %, not by their digits.)

# %% tags=["nbval-ignore-output"]
eng = engine("numpy")
xp = eng.xp
N = 10
true_z = np.array([-1.0, -0.5])
a_true, b_true = dmp.gains_from_logits(true_z[0], true_z[1])
demo = dmp.rollout(np.zeros(1), np.zeros(1), 1.0, a_true, b_true, dmp.DT, N).dy[1:]


def loss(z):
    a, b = dmp.gains_from_logits(z[0], z[1], xp=xp)
    pred = dmp.rollout(xp.zeros(1), xp.zeros(1), 1.0, a, b, dmp.DT, N, xp=xp).dy[1:]
    return xp.mean((pred - demo) ** 2)


z = np.zeros(2)
m, v = np.zeros(2), np.zeros(2)
path, losses = [z], []
for it in range(1, 61):  # Adam, written out
    value, g = eng.value_and_grad(loss)(z)
    losses.append(float(value))
    m = 0.9 * m + 0.1 * g
    v = 0.999 * v + 0.001 * g**2
    z = z - 0.1 * (m / (1 - 0.9**it)) / (np.sqrt(v / (1 - 0.999**it)) + 1e-12)
    path.append(z)
path = np.array(path)
a_fit, b_fit = dmp.gains_from_logits(z[0], z[1])

ZA, ZB = np.meshgrid(np.linspace(-3, 2, 40), np.linspace(-3, 2, 40))
a_g, b_g = dmp.gains_from_logits(ZA.reshape(-1, 1), ZB.reshape(-1, 1))
pred = dmp.rollout(np.zeros(1), np.zeros(1), 1.0, a_g, b_g, dmp.DT, N).dy[1:]  # (N, 1600, 1)
landscape = np.mean((pred - demo[:, None]) ** 2, axis=(0, 2)).reshape(ZA.shape)
fig, axes = plt.subplots(1, 2, figsize=(11, 3.8), layout="constrained")
cs = axes[0].contourf(ZA, ZB, np.log10(landscape), levels=20)
fig.colorbar(cs, ax=axes[0], label="log10 loss")
axes[0].plot(path[:, 0], path[:, 1], "w.-", ms=3)
axes[0].plot(*true_z, "r*", ms=12)
axes[0].set_xlabel("logit of α")
axes[0].set_ylabel("logit of β")
axes[1].semilogy(losses)
axes[1].set_xlabel("iteration")
axes[1].set_ylabel("MSE on velocities")
plt.show()
print(f"true alpha={a_true:.3f} beta={b_true:.3f}; fitted alpha={a_fit:.3f} beta={b_fit:.3f}")
assert abs(a_fit - a_true) < 0.03 * a_true and abs(b_fit - b_true) < 0.03 * b_true


# %% [markdown]
# ## 7. The full DMP of eq. 1: canonical system and forcing term
# MANC drops the forcing term, but it is what makes a DMP a *movement
# primitive*: the point attractor alone can only go straight (or spiral) to
# $g$; the forcing term bends the path into a learned shape. Eq. (1) with its
# canonical system, as `minimanc.dmp` implements it:
#
# $$\tau\ddot y = \alpha\,(\beta\,(g - y) - \dot y) + f(x), \qquad
# \tau\dot x = -\alpha_x x, \qquad
# f(x) = \frac{\sum_i \psi_i(x)\, w_i}{\sum_i \psi_i(x)}\; x\,(g - y_0).$$
#
# ### 7.1 The canonical system
# The phase starts at $x = 1$ and decays, $x(t) = e^{-\alpha_x t/\tau}$. It is a
# clock that runs down: the forcing term is multiplied by it, so it fades
# whatever the weights. The equation is linear, so its *exact* discrete step is
# $x_{k+1} = e^{-\alpha_x \Delta t/\tau} x_k$ (`dmp.canonical_system`); explicit
# Euler, $x_{k+1} = (1 - \alpha_x\Delta t/\tau)\, x_k$, would even turn negative at
# our 0.5 s step once $\alpha_x \Delta t > \tau$.

# %%
alpha_x, T_demo = -np.log(dmp.PHASE_END), 1.0  # x(1 s) = 0.01, as movement_primitives
x_exact = dmp.canonical_system(4, 0.5, 3.0)
x_euler = (1 - 3.0 * 0.5) ** np.arange(5)
print("alpha_x = 3, dt = 0.5: exact", " ".join(f"{v:.4f}" for v in x_exact))
print("             explicit Euler", " ".join(f"{v:+.4f}" for v in x_euler))
assert np.allclose(x_exact, np.exp(-3.0 * 0.5 * np.arange(5)), rtol=1e-14)
print(f"alpha_x for the demonstrations below: -ln(0.01)/1 s = {alpha_x:.4f}")

# %% [markdown]
# ### 7.2 Basis functions spaced in phase
# The forcing term is a normalised mixture of Gaussians in $x$,
# $\psi_i(x) = e^{-\kappa_i (x - c_i)^2}$ with widths $\kappa_i$ (not the step $h$).
# `dmp.basis_centres` follows the
# movement_primitives / Ijspeert convention: the centres are the phase at
# instants *equally spaced in time*, $c_i = e^{-\alpha_x t_i/\tau}$, so they crowd
# together near $x = 0$; each width makes $\psi_i$ fall to one half at the next
# centre. Plotted against time, the bumps are evenly spread over the movement.

# %%
n_basis = 10
centres, widths = dmp.basis_centres(n_basis, alpha_x, T_demo)
tt = np.linspace(0, T_demo, 401)
psi = dmp.basis_functions(dmp.phase(tt, alpha_x), centres, widths)  # (401, 10)
fig, axes = plt.subplots(1, 2, figsize=(12, 3.3))
axes[0].plot(tt, psi)
axes[0].plot(tt, dmp.phase(tt, alpha_x), "k--", label="phase x(t)")
axes[0].set_xlabel("t (s)")
axes[0].set_title("ψ_i(x(t)): equally spaced in time")
axes[0].legend()
axes[1].plot(dmp.phase(tt, alpha_x), psi / psi.sum(1, keepdims=True))
axes[1].set_xlabel("phase x")
axes[1].set_title("normalised ψ_i / Σψ: crowded near x = 0")
plt.show()
half = np.exp(-widths[:-1] * np.diff(centres) ** 2)
print(f"centres (in x): {' '.join(f'{c:.3f}' for c in centres)}")
assert np.allclose(half, 0.5)  # ψ_i is one half at the next centre
peaks = tt[psi.argmax(axis=0)]
assert np.allclose(peaks, np.linspace(0, T_demo, n_basis), atol=tt[1])  # even in time

# %% [markdown]
# ### 7.3 Learning the weights from one demonstration
# `dmp.fit_forcing_weights(demo, dt)` takes positions only. Finite differences
# give $\dot y, \ddot y$; eq. (1) then says what the forcing term must add to the
# point attractor, $f_{target} = \tau\ddot y - \alpha(\beta(g - y) - \dot y)$ with
# $g$ the demo's last point. Locally weighted regression fits each weight on its
# own, a weighted least-squares fit of $f_{target} \approx w_i\, s$ with
# $s = x\,(g - y_0)$ under the weights $\psi_i$:
#
# $$w_i = \frac{\sum_t \psi_i(x_t)\, s_t\, f_{target,t}}{\sum_t \psi_i(x_t)\, s_t^2}.$$
#
# The demonstration: a 2-D reach of 1 s that swerves sideways on the way
# (sampled every 10 ms, at rest at both ends). Gains: the textbook α = 25,
# β = α/4 — fine here, because this DMP is stepped at 10 ms, not 0.5 s.

# %%
dt_demo, a_d, b_d = 0.01, 25.0, 25.0 / 4
t_d = np.arange(101) * dt_demo
sd = t_d / T_demo
min_jerk = 10 * sd**3 - 15 * sd**4 + 6 * sd**5
demo = np.stack([2.0 * min_jerk, 1.0 * min_jerk + 0.8 * np.sin(np.pi * sd) ** 2], axis=-1)
errors = {}
fig, ax = plt.subplots(figsize=(6, 4))
ax.plot(demo[:, 0], demo[:, 1], "k", lw=4, alpha=0.3, label="demonstration")
for nb in (5, 10, 30):
    forcing = dmp.fit_forcing_weights(demo, dt_demo, a_d, b_d, n_basis=nb)
    r = dmp.rollout(demo[0], np.zeros(2), demo[-1], a_d, b_d, dt_demo, 100, forcing=forcing)
    errors[nb] = np.abs(r.y - demo).max()
    ax.plot(r.y[:, 0], r.y[:, 1], label=f"{nb} basis functions")
plain = dmp.rollout(demo[0], np.zeros(2), demo[-1], a_d, b_d, dt_demo, 100)
ax.plot(plain.y[:, 0], plain.y[:, 1], "k:", label="no forcing term")
ax.set_aspect("equal")
ax.legend(fontsize=8)
plt.show()
for nb, e in errors.items():
    print(f"{nb:2d} basis functions: largest deviation from the demo < {np.ceil(e * 100):.0f} cm")
assert errors[30] < errors[10] < errors[5] and errors[30] < 0.03
forcing = dmp.fit_forcing_weights(demo, dt_demo, a_d, b_d, n_basis=30)

# %% [markdown]
# ### 7.4 Generalisation to a new goal
# The factor $g - y_0$ makes the learned shape scale with the movement: with
# $u = (y - y_0)/(g - y_0)$, eq. (1) becomes
# $\tau\ddot u = \alpha(\beta(1 - u) - \dot u) + x\,\sum\psi_i w_i/\sum\psi_i$, which does
# not depend on $g$. So a new goal stretches each coordinate of the same motion
# about the start, and — because $x \to 0$ — every rollout ends exactly at its
# goal (`tests/test_dmp_forcing.py` checks both).

# %%
goals = np.array([[2.0, 1.0], [1.5, 2.0], [3.0, -0.5], [-1.0, 1.5]])
fig, ax = plt.subplots(figsize=(6, 4))
for goal_new in goals:
    r = dmp.rollout(demo[0], np.zeros(2), goal_new, a_d, b_d, dt_demo, 300, forcing=forcing)
    ax.plot(r.y[:, 0], r.y[:, 1])
    ax.plot(*goal_new, "k*", ms=10)
    k = (goal_new - demo[0]) / (demo[-1] - demo[0])
    assert np.allclose(r.y[:101], demo[0] + k * (dmp.rollout(
        demo[0], np.zeros(2), demo[-1], a_d, b_d, dt_demo, 100, forcing=forcing).y - demo[0]))
    assert np.abs(r.y[-1] - goal_new).max() < 1e-3  # at the goal after 3 s
    print(f"goal ({goal_new[0]:+.1f}, {goal_new[1]:+.1f}): reached to within 1 mm")
ax.set_aspect("equal")
ax.set_title("one demonstration, four goals")
plt.show()

# %% [markdown]
# ### 7.5 Why the forcing term must fade
# Take the gate $x$ out of $f$ (`gate=False`). As $x \to 0$ the normalised
# basis settles on its last functions and $f$ tends to a constant
#
# $$f_\infty = \frac{\sum_i \psi_i(0)\, w_i}{\sum_i \psi_i(0)}\,(g - y_0).$$
#
# A constant force
# moves the rest point of eq. (1): $0 = \alpha(\beta(g - y) - 0) + f_\infty$ gives
# $y_\infty = g + f_\infty/(\alpha\beta)$ — the DMP never reaches its goal. This
# is what the paper means by "if they are always kept in effect, then the
# system may never reach the goal state", and why MANC, which drives for an
# unbounded time with no phase to run down, drops $f$.

# %%
long = dict(dt=0.05, steps=80, substeps=5, forcing=forcing)  # 4 s
gated = dmp.rollout(demo[0], np.zeros(2), demo[-1], a_d, b_d, **long)
ungated = dmp.rollout(demo[0], np.zeros(2), demo[-1], a_d, b_d, gate=False, **long)
f_inf = dmp.forcing_term(0.0, forcing, demo[-1], demo[0], gate=False)
rest = demo[-1] + f_inf / (a_d * b_d)
t_long = np.arange(81) * 0.05
fig, axes = plt.subplots(1, 2, figsize=(12, 3.6))
axes[0].plot(demo[:, 0], demo[:, 1], "k", lw=4, alpha=0.3, label="demonstration")
axes[0].plot(gated.y[:, 0], gated.y[:, 1], label="f gated by x (eq. 1)")
axes[0].plot(ungated.y[:, 0], ungated.y[:, 1], label="f never fades")
axes[0].plot(*demo[-1], "k*", ms=12, label="goal")
axes[0].plot(*rest, "rx", ms=10, label="g + f∞/(αβ)")
axes[0].legend(fontsize=8)
axes[0].set_aspect("equal")
axes[1].semilogy(t_long, np.linalg.norm(gated.y - demo[-1], axis=-1) + 1e-12, label="gated")
axes[1].semilogy(t_long, np.linalg.norm(ungated.y - demo[-1], axis=-1), label="never fades")
axes[1].set_xlabel("t (s)")
axes[1].set_ylabel("distance to the goal")
axes[1].legend()
plt.show()
gap_gated = np.linalg.norm(gated.y[-1] - demo[-1])
gap_ungated = np.linalg.norm(ungated.y[-1] - demo[-1])
print(f"after 4 s: gated within 1 mm of the goal: {gap_gated < 1e-3}; never fading "
      f"{gap_ungated:.2f} m off, at the predicted rest point g + f_inf/(alpha beta)")
assert gap_gated < 1e-3 and gap_ungated > 0.1
assert np.allclose(ungated.y[-1], rest, atol=1e-4)

# %% [markdown]
# ### 7.6 The paper's ζ < 0
# The paper warns that the system "can become unstable when ζ < 0". With
# ζ = α/(2√(αβ)) that needs α < 0 *and* β < 0 (αβ > 0): negative damping and a
# repelling spring. `dmp.rollout` refuses negative gains — the error names the
# opt-in — and runs them with `allow_unstable=True` and one `RuntimeWarning`.
# A sigmoid head (the paper's, and `dmp.gains_from_logits`) can never output them.

# %% tags=["raises-exception"]
dmp.rollout(np.array([1.0]), np.zeros(1), 0.0, -2.0, -0.5, 0.5, 12)

# %%
with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always")
    neg = dmp.rollout(np.array([1.0]), np.zeros(1), 0.0, -2.0, -0.5, 0.5, 12,
                      allow_unstable=True)
assert len(caught) == 1 and issubclass(caught[0].category, RuntimeWarning)
print(f"zeta = {dmp.damping_ratio(-2.0, -0.5):.1f} ({dmp.classify(-2.0, -0.5)}); "
      f"RuntimeWarning: {'unstable' in str(caught[0].message)}")
pos = dmp.rollout(np.array([1.0]), np.zeros(1), 0.0, 2.0, 0.5, 0.5, 12)
fig, ax = plt.subplots(figsize=(7, 3))
ax.semilogy(np.arange(13) * 0.5, np.abs(neg.y[:, 0]), "o-", label="α = −2, β = −0.5 (ζ = −1)")
ax.semilogy(np.arange(13) * 0.5, np.abs(pos.y[:, 0]), "o-", label="α = 2, β = 0.5 (ζ = 1)")
ax.set_xlabel("t (s)")
ax.set_ylabel("|y − g|")
ax.legend()
plt.show()
assert abs(neg.y[-1, 0]) > 1e3 and abs(pos.y[-1, 0]) < 0.1

# %% [markdown]
# ### 7.7 Why MANC's head outputs gains only
# Eqs. (10)–(11) replace $f$ by learned gains: `FC(q)` outputs α and β (for
# position and orientation) and nothing else, so the model in chapter 8
# (`minimanc.models`) keeps a gain-only head. Three reasons, all visible above:
# a driving episode has no end time for the phase to run down over (7.1), so
# $f$ would either fade too early or — kept in effect — pull the car off its
# goal (7.5), "overturning the point attractor"; and with gains in a sigmoid box
# the whole family is stable by construction (sections 3–4), which no bound on
# the weights $w_i$ gives for $f$.

# %% [markdown]
# ## How the Euler bounds move with β
# Before the summary, one number the section-3 map hides: the largest stable α of
# one step of 0.5 s as β grows, for both Euler schemes (`dmp.max_stable_alpha`).

# %%
betas_sum = np.array([0.1, 1.0, 1.9])
bounds_sum = {m: np.array([dmp.max_stable_alpha(b, 0.5, m, 1) for b in betas_sum])
              for m in ("euler", "semi_implicit")}
for m, bnd in bounds_sum.items():
    print(f"{m:14s} h = 0.5: largest stable alpha at beta = 0.1, 1.0, 1.9: "
          + ", ".join(f"{v:.2f}" for v in bnd))
print(f"explicit Euler at beta = 2.0 (h beta = 1): "
      f"{dmp.max_stable_alpha(2.0, 0.5, 'euler', 1):.2f}")
assert np.all(np.diff(bounds_sum["euler"]) > 0)          # explicit Euler: rises with beta
assert np.all(np.diff(bounds_sum["semi_implicit"]) < 0)  # semi-implicit Euler: falls
assert dmp.max_stable_alpha(2.0, 0.5, "euler", 1) == 0.0

# %% [markdown]
# ## Summary
# * ζ (eq. 13) describes the *continuous* system: any α, β > 0 converge.
# * The *discrete* step is stable only inside a region that depends on the
#   integrator and the step: at 0.5 s, explicit Euler needs hβ < 1, and below that
#   its largest stable α *rises* with β (the cell above; exercise 3.3 derives the
#   bound) before it collapses to no stable α at all at hβ = 1; the semi-implicit
#   bound *falls* as β grows; the textbook α = 25 diverges. Check with
#   `dmp.spectral_radius`; `dmp.step` and `dmp.rollout` refuse such a step unless
#   `allow_unstable=True`.
# * `dmp.gains_from_logits` keeps learned gains in a box that is stable with
#   the default integrator and bounds ζ away from 0; `dmp.zeta_penalty` and
#   `critically_damped=True` are the paper's extra guards.
# * The full DMP of eq. 1 (`rollout(..., forcing=dmp.fit_forcing_weights(demo, dt))`)
#   learns a shape from one demonstration and carries it to new goals, because
#   the phase x gates the forcing term; without the gate it never reaches the goal.
# * Next, chapter 4 does the same for orientations: quaternions.

# %% [markdown]
# ## Paper vs. this course
# Where this chapter departs from the paper (section III-A, eq. 1; section IV-C,
# eqs. 10–13), and where the paper itself slips:
#
# * **Eq. 1's canonical system has a sign slip.** It reads $\tau\dot x = \alpha_x x$;
#   with α_x > 0 the phase would grow and the forcing term would never fade.
#   It must be $\tau\dot x = -\alpha_x x$ (Ijspeert et al.), as in `dmp.phase`.
# * **Eq. 1's form of τ.** The paper writes $\tau\ddot y = \alpha(\beta(g - y) - \dot y) + f$;
#   Ijspeert's original is $\tau\dot z = \alpha(\beta(g - y) - z) + f$, $\tau\dot y = z$.
#   They agree at τ = 1, which is what every example here uses; `dmp.rollout`
#   implements the paper's form (`tau` enters as the gain α/τ).
# * **The forcing term's details are ours.** The paper says only "a linear
#   combination of N RBFs". We follow movement_primitives / Ijspeert: Gaussians
#   in phase, normalised, gated by x, scaled by $g - y_0$, α_x such that
#   x(T) = 0.01, weights by locally weighted regression.
# * **ζ < 0 needs both gains negative.** "Unstable when ζ < 0": ζ = α/(2√(αβ))
#   is real only for αβ > 0, so ζ < 0 means α < 0 and β < 0; one negative gain
#   makes ζ undefined — and the system unstable too (`dmp.classify` says
#   "unstable" for either).
# * **"Too close together" is backwards.** The paper suggests an auxiliary loss
#   against α and β "too close together" to avoid ζ ≈ 0; but ζ = ½√(α/β) is 1/2
#   when α = β. ζ → 0 needs β ≫ α; `dmp.zeta_penalty` penalises ζ < ζ_min
#   directly.
# * **FC(q)'s list.** After eq. 11 the paper writes FC(q) = {α_y, β_y, α_y, β_y};
#   the last two should be α_q, β_q, the orientation gains of eq. 10.
# * **Stability of the step, not only of the ODE.** The paper analyses eq. 12
#   in continuous time. At its 0.5 s data rate the discrete step matters too
#   (section 3); our gains live in a box (`ALPHA_RANGE` × `BETA_RANGE`) where the
#   default integrator (semi-implicit Euler, 10 sub-steps) is stable, instead of
#   the paper's bare sigmoid into (0, 1).
