# %% [markdown]
# # Chapter 6 — Exercises: class activation maps, Grad-CAM, baselines, q-state saliency
#
# Module built in this chapter: `minimanc.cam` (paper section IV-A, eq. 7,
# and the saliency maps of the execution traces, section V). Replace each
# `raise NotImplementedError(...)` with your code and run the grade cell
# below it; `minimanc grade exercises/06_cam.ipynb` scores the notebook.
#
# Layouts: features are channels-last `(B, H, W, K)`; the linear head's weight
# is `(K, M)` so that `p = gap(f) @ w + b`; CAMs are `(B, M, H, W)`; vAGN
# weights `W` are `(M, N, N)` and q-distributions `(N,)` or `(B, N)`.

# %%
import matplotlib.pyplot as plt
import numpy as np

from minimanc import cam, vagn
from minimanc.viz.saliency import overlay, plot_overlay_attempts

rng = np.random.default_rng(0)

# %% [markdown]
# ## Exercise 6.1 — class activation maps
# For features `(B, H, W, K)` and head weights `w` of shape `(K, M)`, return
# $M_i(x, y) = \sum_k w_{ki} f_k(x, y)$ with shape `(B, M, H, W)` (predicate
# axis before the spatial axes). No bias: the bias is not located anywhere in
# the image. Because only an average and a linear map follow the features,
# $\mathrm{mean}_{xy} M_i + b_i = p_i$ exactly — the CAM identity the tests check.

# %% solution id=ex06_1 title="Class activation maps" forbids="minimanc.cam.class_activation_maps"  # noqa: E501
def class_activation_maps(features, w):
    ### BEGIN SOLUTION
    return np.einsum("bhwk,km->bmhw", np.asarray(features, float), np.asarray(w, float))
    ### END SOLUTION

# %% grade id=ex06_1_tests points=3
f = rng.random((2, 4, 5, 3))
w = rng.normal(size=(3, 2))
b = rng.normal(size=2)
maps = class_activation_maps(f, w)
assert maps.shape == (2, 2, 4, 5), (
    f"expected CAMs of shape (B, M, H, W) = (2, 2, 4, 5); got {maps.shape}")
p = f.mean(axis=(1, 2)) @ w + b
assert np.allclose(maps.mean(axis=(2, 3)) + b, p), (
    f"random f (2, 4, 5, 3): expected the CAM identity mean_xy M_i + b_i = p_i = "
    f"{np.round(p, 4).tolist()}; got {np.round(maps.mean(axis=(2, 3)) + b, 4).tolist()}")
assert np.allclose(maps[1, 0], f[1] @ w[:, 0]), (
    f"image 1, predicate 0: expected sum_k w[k, 0] f_k = f[1] @ w[:, 0], e.g. pixel (0, 0) "
    f"{f[1, 0, 0] @ w[:, 0]:.4f}; got {maps[1, 0, 0, 0]:.4f}")
### BEGIN HIDDEN TESTS
test_rng = np.random.default_rng(610)  # the tests' own draws, not the notebook's rng
fr, wr = test_rng.normal(size=(3, 6, 2, 5)), test_rng.normal(size=(5, 4))
ref = np.stack([[fr[n] @ wr[:, m] for m in range(4)] for n in range(3)])
got = np.asarray(class_activation_maps(fr, wr))
assert got.shape == ref.shape and np.allclose(got, ref), (
    f"random f (3, 6, 2, 5), w (5, 4): expected f[n] @ w[:, m] for every image n and "
    f"predicate m, shape {ref.shape}; got shape {got.shape}"
    + (f", largest difference {np.abs(got - ref).max():.3g}" if got.shape == ref.shape else ""))
one = np.zeros((1, 2, 2, 2))
one[0, 1, 0] = [1.0, 2.0]
got = np.asarray(class_activation_maps(one, np.array([[3.0], [-1.0]])))[0, 0]
assert np.allclose(got, [[0.0, 0.0], [1.0, 0.0]]), (
    f"one pixel with f = (1, 2) and w = (3, -1): expected [[0, 0], [1, 0]]; got {got.tolist()}")
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 6.2 — the overlay normalisation
# Overlays show the *ranking* of pixels, so each map is min–max normalised to
# $[0, 1]$: $(s - \min s)/(\max s - \min s)$, separately for every map of a
# stack `(..., H, W)`. A constant map has no ranking: return zeros for it
# (not `nan`).

# %% solution id=ex06_2 title="Min-max normalisation of saliency maps" forbids="minimanc.cam.minmax_normalize"  # noqa: E501
def normalise(maps):
    ### BEGIN SOLUTION
    maps = np.asarray(maps, float)
    lo = maps.min(axis=(-2, -1), keepdims=True)
    span = maps.max(axis=(-2, -1), keepdims=True) - lo
    return np.where(span > 0, (maps - lo) / np.where(span > 0, span, 1.0), 0.0)
    ### END SOLUTION

# %% grade id=ex06_2_tests points=2
s = np.array([[1.0, 3.0], [5.0, 2.0]])
assert np.allclose(normalise(s), [[0.0, 0.5], [1.0, 0.25]]), (
    f"(s - 1) / (5 - 1) = [[0, 0.5], [1, 0.25]]; got {normalise(s)}")
stack = np.stack([s, 10 * s - 4])
got = np.asarray(normalise(stack))
assert np.allclose(got, normalise(s)[None]), (
    f"the stack [s, 10 s - 4], each map on its own: expected both [[0, 0.5], [1, 0.25]]; "
    f"got {np.round(got, 4).tolist()}")
flat = np.asarray(normalise(np.full((3, 3), 7.0)))
assert np.all(np.isfinite(flat)) and np.allclose(flat, 0.0), (
    f"a constant 3 x 3 map: expected zeros (not nan); got {flat.tolist()}")
### BEGIN HIDDEN TESTS
test_rng = np.random.default_rng(620)  # the tests' own draws, not the notebook's rng
sr = test_rng.normal(size=(2, 3, 6, 5))
lo, hi = sr.min(axis=(2, 3), keepdims=True), sr.max(axis=(2, 3), keepdims=True)
got, ref = np.asarray(normalise(sr)), (sr - lo) / (hi - lo)
assert got.shape == ref.shape and np.allclose(got, ref), (
    f"a (2, 3, 6, 5) stack, over the last two axes only: expected map (0, 0) to span "
    f"[0, 1]; got shape {got.shape}, map (0, 0) from {got[0, 0].min():.3f} to "
    f"{got[0, 0].max():.3f}" if got.ndim == 4 else f"expected shape (2, 3, 6, 5); got {got.shape}")
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 6.3 — Grad-CAM
# Grad-CAM (Selvaraju et al. 2017) needs only the features $f_k(x, y)$ and the
# gradient $g_k(x, y) = \partial y / \partial f_k(x, y)$ of one score $y$: weigh
# each feature map by its average gradient and keep the positive part,
#
# $$\alpha_k = \mathrm{mean}_{xy}\, g_k(x, y),\qquad
#   \text{Grad-CAM}(x, y) = \mathrm{ReLU}\Big(\sum_k \alpha_k f_k(x, y)\Big).$$
#
# `features` and `grads` are `(B, H, W, K)`; return `(B, H, W)`. The tests
# check what the tutorial claims: for conv → GAP → linear the gradient is
# $W_{ki}/(HW)$ at every pixel, so Grad-CAM is $\mathrm{ReLU}(M_i)/(HW)$.

# %% solution id=ex06_3 title="Grad-CAM" forbids="minimanc.cam.grad_cam"
def grad_cam(features, grads):
    ### BEGIN SOLUTION
    features, grads = np.asarray(features, float), np.asarray(grads, float)
    alpha = grads.mean(axis=(-3, -2))                       # (B, K)
    return np.maximum(np.einsum("bhwk,bk->bhw", features, alpha), 0.0)
    ### END SOLUTION

# %% grade id=ex06_3_tests points=2
f = np.zeros((1, 2, 2, 2))
f[0, 0, 0] = [1.0, 0.0]
f[0, 1, 1] = [0.0, 1.0]
g = np.zeros((1, 2, 2, 2))
g[0, 0, 0] = [4.0, -8.0]                  # alpha = mean over the 4 pixels = (1, -2)
gc = grad_cam(f, g)
assert gc.shape == (1, 2, 2), f"expected Grad-CAM of shape (B, H, W) = (1, 2, 2); got {gc.shape}"
assert np.allclose(gc, [[[1.0, 0.0], [0.0, 0.0]]]), (
    f"alpha = (1, -2): pixel (0, 0) gives 1, pixel (1, 1) gives ReLU(-2) = 0; got {gc}")
fr = rng.random((3, 4, 5, 6))
wr = rng.normal(size=(6, 2))
gr = np.broadcast_to(wr[:, 1] / 20, fr.shape)   # d p_1 / d f for conv -> GAP -> linear
got, ref = np.asarray(grad_cam(fr, gr)), np.maximum(fr @ wr[:, 1], 0) / 20
assert got.shape == ref.shape and np.allclose(got, ref), (
    f"the gradient of conv -> GAP -> linear (4 x 5 features): expected ReLU(CAM_1) / (H W), "
    f"e.g. image 0, pixel (0, 0): {ref[0, 0, 0]:.4f}; got "
    f"{got[0, 0, 0] if got.ndim == 3 else got.shape}")
### BEGIN HIDDEN TESTS
test_rng = np.random.default_rng(630)  # the tests' own draws, not the notebook's rng
fr, gr = test_rng.normal(size=(2, 3, 4, 5)), test_rng.normal(size=(2, 3, 4, 5))
ref = np.zeros((2, 3, 4))
for n in range(2):
    a = [gr[n, :, :, k].sum() / 12 for k in range(5)]
    for y in range(3):
        for x in range(4):
            ref[n, y, x] = max(0.0, sum(a[k] * fr[n, y, x, k] for k in range(5)))
got = np.asarray(grad_cam(fr, gr))
assert got.shape == ref.shape and np.allclose(got, ref), (
    f"random features and gradients, each image with its own alpha_k = mean_xy g_k: expected "
    f"image 1 = {np.round(ref[1], 3).tolist()}; got "
    f"{np.round(got[1], 3).tolist() if got.shape == ref.shape else got.shape}")
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 6.4 — the data-set baseline
# CAMs are defined only up to a map that is the same in every image: adding
# $B_i(x, y)$ to $M_i$ and $-\mathrm{mean}_{xy} B_i$ to $b_i$ gives the same
# predictor. The ego vehicle, present in every BEV, can therefore carry any
# amount of CAM mass. Remove it with the **data-set baseline**, the mean CAM
# over the training images $\bar M_i(x, y)$:
#
# $$\tilde M_i = M_i - \bar M_i,\qquad \tilde b_i = b_i + \mathrm{mean}_{xy} \bar M_i,$$
#
# so that $\mathrm{mean}_{xy}\tilde M_i + \tilde b_i = p_i$ still holds. Given
# `cams` `(B, M, H, W)`, the training CAMs `train_cams` `(B', M, H, W)` and the
# bias `b` `(M,)`, return `(centred_cams, new_bias)`.

# %% solution id=ex06_4 title="CAMs centred on the data-set baseline" forbids="minimanc.cam.explain"  # noqa: E501
def centre_on_baseline(cams, train_cams, b):
    ### BEGIN SOLUTION
    baseline = np.asarray(train_cams, float).mean(axis=0)      # (M, H, W)
    return np.asarray(cams, float) - baseline, np.asarray(b, float) + baseline.mean(axis=(-2, -1))
    ### END SOLUTION

# %% grade id=ex06_4_tests points=3
train = np.array([[[[1.0, 3.0]]], [[[3.0, 5.0]]]])      # (2, 1, 1, 2): baseline [[2, 4]]
test = np.array([[[[2.0, 7.0]]]])
c, b_new = centre_on_baseline(test, train, np.array([0.5]))
assert np.allclose(c, [[[[0.0, 3.0]]]]), f"test CAM minus baseline [[2, 4]] = [[0, 3]]; got {c}"
assert np.allclose(b_new, [3.5]), f"new bias = 0.5 + mean(baseline) = 0.5 + 3 = 3.5; got {b_new}"
cams_r, train_r = rng.normal(size=(4, 3, 5, 6)), rng.normal(size=(9, 3, 5, 6))
b_r = rng.normal(size=3)
c, b_new = centre_on_baseline(cams_r, train_r, b_r)
p_before = cams_r.mean(axis=(-2, -1)) + b_r
p_after = np.asarray(c).mean(axis=(-2, -1)) + b_new
assert np.allclose(p_after, p_before), (
    f"random CAMs: expected unchanged predictions mean_xy(centred) + new bias = "
    f"{np.round(p_before[0], 4)} for image 0; got {np.round(p_after[0], 4)}")
### BEGIN HIDDEN TESTS
c_tr, _ = centre_on_baseline(train_r, train_r, b_r)
worst = np.abs(np.asarray(c_tr).mean(axis=0)).max()
assert worst < 1e-9, (
    f"the training CAMs centred on their own baseline: expected mean 0; got up to {worst:.3g}")
test_rng = np.random.default_rng(640)  # the tests' own draws, not the notebook's rng
ego = test_rng.normal(size=(3, 5, 6))            # a map common to every image
c2, b2 = centre_on_baseline(cams_r + ego, train_r + ego, b_r - ego.mean(axis=(-2, -1)))
assert np.allclose(c2, c) and np.allclose(b2, b_new), (
    f"the same map added to every CAM (its mean taken from b): expected the same centred "
    f"CAMs and bias {np.round(b_new, 4)}; got bias {np.round(b2, 4)}, CAMs off by up to "
    f"{np.abs(np.asarray(c2) - c).max():.3g}")
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 6.5 — where does each q-state look?
# One vAGN step (chapter 5, eq. 9) turns the predicates into
# $q = \mathrm{colsoftmax}(\mathrm{ReLU}(\sum_i p_i W_i))\, q_{prev}$. The
# per-q-state saliency carries the CAMs through it by the first-order
# influence of each predicate on each state:
#
# $$J_{ji} = \frac{\partial q_j}{\partial p_i},\qquad S_j(x, y) = \sum_i J_{ji}\, M_i(x, y).$$
#
# Given `q_prev` `(N,)`, predicates `p` `(B, M)`, weights `W` `(M, N, N)` and
# CAMs `cams` `(B, M, H, W)`, return `S` `(B, N, H, W)`. Get $J$ from
# `vagn.step(q_prev, p, W)` (the library's eq. 9, allowed here) by **central
# differences** — $J_{:, i} \approx (q(p + h e_i) - q(p - h e_i)) / 2h$ with
# $h = 10^{-6}$, every image at once since the rows of `p` are independent —
# or with `engine("numpy").grad` of $\sum_{batch} q_j$, one $j$ at a time.
#
# <details><summary>Hint 1 (the idea)</summary>
#
# $J$ has one column per predicate: how much does q move when only $p_i$
# moves? The rows of `p` are independent images, so one perturbed call of
# `vagn.step` serves the whole batch.
# </details>
#
# <details><summary>Hint 2 (two checks you can do yourself)</summary>
#
# Every $\sum_j S_j(x, y)$ is zero (the $q_j$ sum to one whatever $p$ is, so
# $\sum_j J_{ji} = 0$); and with $N = 2$, $M = 1$,
# $W_0 = \begin{pmatrix}1 & 0\\ 0 & 0\end{pmatrix}$, $q_{prev} = (1, 0)$ you get
# $q_0 = \sigma(p)$, so $J_{00} = \sigma(p)(1 - \sigma(p))$.
# </details>

# %% solution id=ex06_5 title="Per-q-state saliency" forbids="minimanc.cam.vagn_jacobian,minimanc.cam.q_state_saliency,minimanc.cam.explain,minimanc.models.saliency"  # noqa: E501
def q_saliency(q_prev, p, W, cams):
    ### BEGIN SOLUTION
    p = np.asarray(p, float)
    h, M = 1e-6, p.shape[-1]
    cols = []
    for i in range(M):
        e = np.zeros(M)
        e[i] = h
        cols.append((vagn.step(q_prev, p + e, W) - vagn.step(q_prev, p - e, W)) / (2 * h))
    J = np.stack(cols, axis=-1)                                # (B, N, M)
    return np.einsum("bji,bihw->bjhw", J, np.asarray(cams, float))
    ### END SOLUTION

# %% grade id=ex06_5_tests points=4
W1 = np.zeros((1, 2, 2))
W1[0, 0, 0] = 1.0
M1 = np.arange(6.0).reshape(1, 1, 2, 3)
S1 = q_saliency(np.array([1.0, 0.0]), np.array([[np.log(3.0)]]), W1, M1)
assert S1.shape == (1, 2, 2, 3), f"expected S of shape (B, N, H, W) = (1, 2, 2, 3); got {S1.shape}"
# sigma(log 3) = 3/4, so J_00 = 3/4 * 1/4 = 0.1875 and J_10 = -0.1875
assert np.allclose(S1[0, 0], 0.1875 * M1[0, 0], atol=1e-6), (
    f"S_0 = sigma'(log 3) M_0 = 0.1875 M_0; got {S1[0, 0]}")
assert np.allclose(S1[0, 1], -0.1875 * M1[0, 0], atol=1e-6), (
    f"S_1 = -0.1875 M_0 (probability leaves q_1 as it enters q_0); got {S1[0, 1]}")
Wr, pr = rng.normal(size=(3, 4, 4)), rng.normal(size=(5, 3))
cams_r = rng.normal(size=(5, 3, 6, 7))
Sr = q_saliency(vagn.uniform_state(4), pr, Wr, cams_r)
worst = np.abs(np.asarray(Sr).sum(axis=1)).max()
assert worst < 1e-6, (
    f"random W (3, 4, 4), 5 images: expected sum_j S_j = 0 at every pixel (the q_j sum to "
    f"one, so sum_j dq_j/dp_i = 0); got up to {worst:.3g}")
### BEGIN HIDDEN TESTS
import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402

from minimanc import engine  # noqa: E402

engine("jax")                               # turns on float64 in JAX
q0 = np.random.default_rng(650).dirichlet(np.ones(4))
Sr = np.asarray(q_saliency(q0, pr, Wr, cams_r))
for n in range(5):
    J = np.asarray(jax.jacobian(lambda pp: vagn.step(q0, pp, Wr, xp=jnp))(jnp.asarray(pr[n])))
    ref = np.einsum("ji,ihw->jhw", J, cams_r[n])
    assert np.allclose(Sr[n], ref, atol=1e-6), (
        f"image {n}, a random q_prev: expected S_j = sum_i (dq_j/dp_i) M_i (JAX's Jacobian of "
        f"eq. 9), e.g. S at pixel (0, 0) = {np.round(ref[:, 0, 0], 5)}; got "
        f"{np.round(Sr[n][:, 0, 0], 5)}")
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 6.6 — CAMs for a head with a hidden ReLU layer
# The CAM identity needs a *linear* head after the pooling. Put a hidden ReLU
# layer in it:
#
# $$z = \mathrm{gap}(f)\,U + b_1,\qquad p = \mathrm{ReLU}(z)\,V + c,$$
#
# with `U` `(K, D)`, `b1` `(D,)`, `V` `(D, M)`, `c` `(M,)`. This head is not
# linear, yet for **each image** it is exactly linear in $\mathrm{gap}(f)$ near
# that image (ReLU is piecewise linear), so each image has its own head weights
# $w^{(n)}$ `(K, M)` and bias $b^{(n)}$ `(M,)` with
# $p^{(n)} = \mathrm{gap}(f^{(n)})\, w^{(n)} + b^{(n)}$ and
# $w^{(n)} = \partial p^{(n)} / \partial\, \mathrm{gap}(f^{(n)})$ (a unit with
# $z_d = 0$ exactly counts as inactive).
#
# 1. `effective_head(features, U, b1, V, c)`: return `(w_eff, b_eff)`, shapes
#    `(B, K, M)` and `(B, M)`. (2 points)
# 2. `mlp_cams(features, U, b1, V, c)`: the CAMs of this head, shape
#    `(B, M, H, W)`, built from each image's own weights, so that
#    $\mathrm{mean}_{xy} M_i + b^{(n)}_i = p_i$ for every image. (2 points)
#
# <details><summary>Hint 1 (the idea)</summary>
#
# Which hidden units pass their input on for this image, and which output 0
# whatever small change you make to it?
# </details>
#
# <details><summary>Hint 2 (the method)</summary>
#
# Write ReLU(z) as $m \odot z$ with the image's 0/1 mask $m = [z > 0]$ and
# expand $(m \odot (gU + b_1))V + c$; separate the part that multiplies $g$.
# The batch axis now sits on the weights too (`np.einsum` with three operands).
# </details>

# %% solution id=ex06_6 title="CAMs for a head with a hidden ReLU layer"
def effective_head(features, U, b1, V, c):
    ### BEGIN SOLUTION
    g = np.asarray(features, float).mean(axis=(1, 2))            # (B, K)
    active = (g @ U + b1 > 0).astype(float)                      # (B, D)
    w_eff = np.einsum("kd,bd,dm->bkm", U, active, V)
    return w_eff, (active * b1) @ V + c
    ### END SOLUTION


def mlp_cams(features, U, b1, V, c):
    ### BEGIN SOLUTION
    w_eff, _ = effective_head(features, U, b1, V, c)
    return np.einsum("bhwk,bkm->bmhw", np.asarray(features, float), w_eff)
    ### END SOLUTION

# %%
def mlp_head(features, U, b1, V, c):
    """The head of 6.6: p = ReLU(gap(f) U + b1) V + c, shape (B, M)."""
    return np.maximum(np.asarray(features).mean(axis=(1, 2)) @ U + b1, 0.0) @ V + c

# %% grade id=ex06_6_head_tests points=2
U6, b16 = np.array([[1.0, -1.0], [0.0, 2.0]]), np.array([0.0, -3.0])
V6, c6 = np.array([[1.0], [5.0]]), np.array([0.5])
f6 = np.zeros((1, 1, 2, 2))              # B = 1, H = 1, W = 2, K = 2
f6[0, 0, 0] = [2.0, 0.0]                 # gap(f) = (1, 0): z = (1, -4), only unit 0 is on
w6, b6 = effective_head(f6, U6, b16, V6, c6)
assert np.shape(w6) == (1, 2, 1) and np.shape(b6) == (1, 1), (
    f"B = 1, K = 2, M = 1: expected shapes (1, 2, 1) and (1, 1); got {np.shape(w6)}, "
    f"{np.shape(b6)}")
assert np.allclose(w6[0, :, 0], [1.0, 0.0]) and np.allclose(b6, 0.5), (
    f"gap(f) = (1, 0), z = (1, -4): expected w = [1, 0], b = 0.5 (unit 1 is off); "
    f"got w = {np.ravel(w6)}, b = {np.ravel(b6)}")
### BEGIN HIDDEN TESTS
test_rng = np.random.default_rng(660)  # the tests' own draws, not the notebook's rng
fr = test_rng.normal(size=(6, 4, 5, 3))
Ur, b1r = test_rng.normal(size=(3, 7)), test_rng.normal(size=7)
Vr, cr = test_rng.normal(size=(7, 2)), test_rng.normal(size=2)
w, b = (np.asarray(x) for x in effective_head(fr, Ur, b1r, Vr, cr))
assert w.shape == (6, 3, 2) and b.shape == (6, 2), (
    f"B = 6, K = 3, M = 2: expected (6, 3, 2) and (6, 2); got {w.shape}, {b.shape}")
g = fr.mean(axis=(1, 2))
for n in range(6):   # the Jacobian of the head at this image, by central differences
    jac = np.stack([(mlp_head(fr[n:n + 1] + e, Ur, b1r, Vr, cr)
                     - mlp_head(fr[n:n + 1] - e, Ur, b1r, Vr, cr))[0] / 2e-6
                    for e in 1e-6 * np.eye(3)])
    assert np.allclose(w[n], jac, atol=1e-6), (
        f"image {n}: expected w_eff = dp/d gap(f) = {np.round(jac, 4).tolist()}; "
        f"got {np.round(w[n], 4).tolist()}")
    p_n = mlp_head(fr[n:n + 1], Ur, b1r, Vr, cr)[0]
    assert np.allclose(g[n] @ w[n] + b[n], p_n), (
        f"image {n}: expected gap(f) w_eff + b_eff = p = {np.round(p_n, 4).tolist()}; "
        f"got {np.round(g[n] @ w[n] + b[n], 4).tolist()}")
### END HIDDEN TESTS

# %% grade id=ex06_6_cams_tests points=2
M6 = np.asarray(mlp_cams(f6, U6, b16, V6, c6))
assert M6.shape == (1, 1, 1, 2), (
    f"B = 1, M = 1, a 1 x 2 feature map: expected CAMs of shape (1, 1, 1, 2); got {M6.shape}")
assert np.allclose(M6[0, 0], [[2.0, 0.0]]), (
    f"pixels f = (2, 0) and (0, 0), w_eff = (1, 0): expected [[2, 0]]; got {M6[0, 0]}")
### BEGIN HIDDEN TESTS
test_rng = np.random.default_rng(661)  # the tests' own draws, not the notebook's rng
fr = test_rng.normal(size=(5, 3, 4, 3))
Ur, b1r = test_rng.normal(size=(3, 6)), test_rng.normal(size=6)
Vr, cr = test_rng.normal(size=(6, 2)), test_rng.normal(size=2)
got = np.asarray(mlp_cams(fr, Ur, b1r, Vr, cr))
assert got.shape == (5, 2, 3, 4), f"B = 5, M = 2, 3 x 4: expected (5, 2, 3, 4); got {got.shape}"
for n in range(5):   # the tests' own per-image weights: the units that are on, written out
    z = fr[n].mean(axis=(0, 1)) @ Ur + b1r
    w_n = sum(np.outer(Ur[:, d], Vr[d]) for d in range(6) if z[d] > 0)
    ref = np.einsum("hwk,km->mhw", fr[n], w_n)
    assert np.allclose(got[n], ref), (
        f"image {n}: expected the CAMs sum_k w_eff[k, i] f_k with its own active units; "
        f"largest difference {np.abs(got[n] - ref).max():.3g}")
    b_n = sum(b1r[d] * Vr[d] for d in range(6) if z[d] > 0) + cr
    p_n = mlp_head(fr[n:n + 1], Ur, b1r, Vr, cr)[0]
    assert np.allclose(got[n].mean(axis=(1, 2)) + b_n, p_n), (
        f"image {n}: expected mean_xy M + b_eff = p = {np.round(p_n, 4).tolist()}; "
        f"got {np.round(got[n].mean(axis=(1, 2)) + b_n, 4).tolist()}")
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 6.7 — open experiment: a head that looks at the ego
# The tutorial's CNN put most of its pedestrian CAM on the ego vehicle and
# called the map *ambiguous*. Make that ambiguity yourself. Below are scenes
# with a road, the ego (red, always at the same place) and, in most, a vehicle
# (yellow), and the hand-made features of "Putting it together": channel 0
# fires on yellow, channel 1 on red. The head `W_VEH = [[2], [0]]`, `B_VEH = [0]`
# predicts *vehicle present* and its CAM sits on the vehicle.
#
# Write `ego_head()` returning `(w, b)`, shapes `(2, 1)` and `(1,)`: a head that
# makes **the same predictions** as `W_VEH`, `B_VEH` on every such scene (to
# 1e-9; the tests draw scenes of their own), but whose raw CAM **peaks on the
# ego** in every scene. Then check with your `centre_on_baseline` (6.4) where
# the centred maps of your head peak. Checked automatically: the predictions,
# the raw peaks on the ego, and the centred peaks back on the vehicle.
# Then answer the written question below the grade cell.

# %%
EGO_BOX = (24, 14, 30, 18)    # rows 24-29, columns 14-17
W_VEH, B_VEH = np.array([[2.0], [0.0]]), np.array([0.0])


def ego_scene(rng, vehicle=True):
    """A 32 x 32 raster: road, ego, and a 6 x 4 yellow vehicle at a random free place."""
    img = np.zeros((32, 32, 3), np.uint8)
    img[:, 8:24] = 255
    img[24:30, 14:18] = (255, 0, 0)
    box = None
    if vehicle:
        r, c = rng.integers(0, 18), rng.integers(8, 20)   # above the ego, on the road
        img[r:r + 6, c:c + 4] = (255, 255, 0)
        box = (int(r), int(c), int(r + 6), int(c + 4))
    return img, box


def hand_features(images):
    """Channel 0: yellow pixels, channel 1: red pixels; shape (B, 32, 32, 2)."""
    x = np.asarray(images) / 255.0
    return np.stack([x[..., 0] * x[..., 1] * (1 - x[..., 2]), x[..., 0] * (1 - x[..., 1])],
                    axis=-1)


rng_e = np.random.default_rng(67)
scenes = [ego_scene(rng_e, vehicle=k % 4 != 0) for k in range(40)]
X_ego = np.stack([s[0] for s in scenes])
F_ego = hand_features(X_ego)
p_veh = F_ego.mean(axis=(1, 2)) @ W_VEH + B_VEH
print("scenes:", X_ego.shape, "| with a vehicle:", sum(s[1] is not None for s in scenes))
assert np.allclose(p_veh[:, 0][[s[1] is None for s in scenes]], 0.0)

# %% solution id=ex06_7 title="Open experiment: a head whose CAM looks at the ego"
def ego_head():
    ### BEGIN SOLUTION
    # the ego's red mass is the same in every scene (24 of 1024 pixels): any weight on
    # the red channel adds a constant to p, which the bias takes back
    w_red = 5.0                                   # above the yellow weight 2: the ego wins
    return np.array([[2.0], [w_red]]), np.array([-w_red * 24 / 1024])
    ### END SOLUTION

# %% grade id=ex06_7_tests points=3
w7, b7 = (np.asarray(x, dtype=float) for x in ego_head())
assert w7.shape == (2, 1) and b7.shape == (1,), (
    f"expected w of shape (2, 1) and b of shape (1,); got {w7.shape}, {b7.shape}")
p7 = F_ego.mean(axis=(1, 2)) @ w7 + b7
assert np.allclose(p7, p_veh, atol=1e-9, rtol=0), (
    f"the 40 scenes: expected the predictions of W_VEH, B_VEH; largest difference "
    f"{np.abs(p7 - p_veh).max():.2e}")
### BEGIN HIDDEN TESTS
test_rng = np.random.default_rng(670)  # the tests' own scenes
held = [ego_scene(test_rng, vehicle=k % 5 != 0) for k in range(30)]
F_h = hand_features(np.stack([s[0] for s in held]))
p_h = F_h.mean(axis=(1, 2)) @ w7 + b7
ref_h = F_h.mean(axis=(1, 2)) @ W_VEH + B_VEH
assert np.allclose(p_h, ref_h, atol=1e-9, rtol=0), (
    f"the tests' own 30 scenes: expected the predictions of W_VEH, B_VEH; largest "
    f"difference {np.abs(p_h - ref_h).max():.2e}")
raw = F_h @ w7[:, 0]                              # (30, 32, 32), the CAMs written out
centred = raw - raw.mean(axis=0)                  # the data-set baseline, written out
r0, c0, r1, c1 = EGO_BOX
for k, (_, box) in enumerate(held):
    r, c = np.unravel_index(np.argmax(raw[k]), raw[k].shape)
    assert r0 <= r < r1 and c0 <= c < c1, (
        f"scene {k}: expected the raw CAM's peak on the ego (rows 24-29, cols 14-17); "
        f"got ({r}, {c})")
    if box is not None:
        r, c = np.unravel_index(np.argmax(centred[k]), centred[k].shape)
        assert box[0] <= r < box[2] and box[1] <= c < box[3], (
            f"scene {k}: expected the centred CAM's peak on the vehicle {box}; got ({r}, {c})")
### END HIDDEN TESTS

# %% [markdown]
# **Written question (6.7).** Your head and `W_VEH` make the same predictions
# on every scene; their raw CAMs disagree completely. Which one is "right", and
# what does that say about reading a raw CAM as the answer to "where does the
# network look"? Why does the data-set baseline (6.4) repair your head here,
# and describe a data set on which it would *not* (where would the baseline
# fail to tell the ego from the object)?

# %% [markdown] answer id=ex06_7_w title="Which CAM is right" points=2
# ### BEGIN SOLUTION
# Neither is more right: the two heads are the same predictor on this data,
# because the ego's red mass is identical in every scene, so w_red·(red mass) is
# a constant that the bias cancels. The CAM splits p over pixels, but only up to
# a map common to all images (6.4), so a raw CAM answers "where is the evidence
# *in this decomposition*", not "where does the network look"; a reading needs
# a reference. The data-set baseline subtracts the mean CAM, which contains the
# ego's contribution exactly (it is the same in every scene): what remains is
# what makes this scene differ from the average one — the vehicle. It fails
# when the nuisance is not constant: an ego that moves or changes size, or an
# object that is present in (almost) every training image, or correlated with
# the label (e.g. the vehicle always next to a lane marking): its mean is then
# not its value in the image, and the centred map keeps (or removes) mass that
# does (or does not) belong to the object.
# ### END SOLUTION

# %% [markdown]
# ## Putting it together
# The library's versions from here on. A hand-made feature extractor with two
# maps — "yellow pixels" (vehicles) and "red pixels" (the ego) — and a head
# that only counts vehicles: its CAM lands on the vehicle and ignores the ego.

# %%
img = np.zeros((32, 32, 3), np.uint8)
img[:, 8:24] = 255                       # road
img[24:30, 14:18] = (255, 0, 0)          # ego
img[5:11, 18:22] = (255, 255, 0)         # a vehicle
x = img / 255.0
features = np.stack([x[..., 0] * x[..., 1] * (1 - x[..., 2]),        # yellow
                     x[..., 0] * (1 - x[..., 1])], axis=-1)[None]   # red
w = np.array([[2.0], [0.0]])             # K = 2 features -> M = 1 predicate
maps = cam.class_activation_maps(features, w)
r, c = cam.peak_location(maps[0, 0])
print("CAM peak at row", int(r), "col", int(c))
assert 5 <= r < 11 and 18 <= c < 22
fig, axes = plt.subplots(1, 2, figsize=(5, 2.6))
axes[0].imshow(img, interpolation="nearest")
axes[0].axis("off")
overlay(img, maps[0, 0], ax=axes[1], title="'vehicle' CAM")
plt.show()

# %% [markdown]
# Through a vAGN with two q-states, *cruise* and *follow*, whose single
# weight matrix sends probability to *follow* when the vehicle predicate is
# positive: the *follow* saliency is the vehicle CAM scaled by
# $\partial q_{follow}/\partial p > 0$, the *cruise* saliency its mirror image.

# %%
W_demo = np.zeros((1, 2, 2))
W_demo[0, 1, :] = 1.0                     # vehicle predicate -> follow
p_demo = maps.mean(axis=(-2, -1))         # the CAM identity with b = 0
J = cam.vagn_jacobian(vagn.uniform_state(2), p_demo, W_demo)
S = cam.q_state_saliency(maps, J)
print("dq/dp =", np.round(J[0, :, 0], 4))
assert J[0, 1, 0] > 0 and np.isclose(J[0, 0, 0], -J[0, 1, 0])
assert tuple(cam.peak_location(S[0, 1])) == (int(r), int(c))

# %% [markdown]
# ## Your figure
# One scene of 6.7, with maps made by **your** functions: the vehicle head's CAM
# (your `class_activation_maps`, normalised by your `normalise`), your
# `ego_head`'s raw CAM (it should sit on the ego) and the same map centred by
# your `centre_on_baseline` over the 40 scenes (back on the vehicle). A
# function that raises is named, and the library's map (where there is one) drawn.

# %%
k_fig = next(k for k, (_, box) in enumerate(scenes) if box is not None)


def ego_cams():
    """CAMs (40, 1, 32, 32) of your ego_head over the 40 scenes, and its bias."""
    w, b = ego_head()
    return class_activation_maps(F_ego, np.asarray(w)), np.asarray(b)


print("the vehicle in this scene:", scenes[k_fig][1])
plot_overlay_attempts(X_ego[k_fig], [
    ("vehicle CAM", lambda: normalise(class_activation_maps(F_ego[k_fig:k_fig + 1], W_VEH)[0, 0]),
     cam.class_activation_maps(F_ego[k_fig:k_fig + 1], W_VEH)[0, 0]),
    ("ego head, raw", lambda: ego_cams()[0][k_fig, 0], None),
    ("ego head, centred", lambda: centre_on_baseline(*ego_cams()[:1], ego_cams()[0],
                                                     ego_cams()[1])[0][k_fig, 0], None)])
plt.show()

