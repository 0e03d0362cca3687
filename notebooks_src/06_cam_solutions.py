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
from minimanc.viz.saliency import overlay

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
    "the CAM identity mean_xy M_i + b_i = p_i must hold (p = gap(f) @ w + b)")
assert np.allclose(maps[1, 0], f[1] @ w[:, 0]), (
    "M_0 of image 1 must be sum_k w[k, 0] f_k, i.e. f[1] @ w[:, 0]")
### BEGIN HIDDEN TESTS
fr, wr = rng.normal(size=(3, 6, 2, 5)), rng.normal(size=(5, 4))
ref = np.stack([[fr[n] @ wr[:, m] for m in range(4)] for n in range(3)])
assert np.allclose(class_activation_maps(fr, wr), ref), (
    "CAMs of random features must equal f[n] @ w[:, m] for every image n and predicate m")
one = np.zeros((1, 2, 2, 2))
one[0, 1, 0] = [1.0, 2.0]
assert np.allclose(class_activation_maps(one, np.array([[3.0], [-1.0]]))[0, 0],
                   [[0.0, 0.0], [1.0, 0.0]]), (
    "one pixel with f = (1, 2) and w = (3, -1): M = 3 - 2 = 1 there, 0 elsewhere")
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
assert np.allclose(normalise(stack), normalise(s)[None]), (
    "each map of a stack is normalised separately: 10 s - 4 normalises like s")
flat = normalise(np.full((3, 3), 7.0))
assert np.all(np.isfinite(flat)) and np.allclose(flat, 0.0), (
    "a constant map must become zeros, not nan")
### BEGIN HIDDEN TESTS
sr = rng.normal(size=(2, 3, 6, 5))
lo, hi = sr.min(axis=(2, 3), keepdims=True), sr.max(axis=(2, 3), keepdims=True)
assert np.allclose(normalise(sr), (sr - lo) / (hi - lo)), (
    "a (2, 3, 6, 5) stack must be normalised over its last two axes only")
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
assert np.allclose(grad_cam(fr, gr), np.maximum(fr @ wr[:, 1], 0) / 20), (
    "with the gradient of conv -> GAP -> linear, Grad-CAM must equal ReLU(CAM_1) / (H W)")
### BEGIN HIDDEN TESTS
fr, gr = rng.normal(size=(2, 3, 4, 5)), rng.normal(size=(2, 3, 4, 5))
ref = np.zeros((2, 3, 4))
for n in range(2):
    a = [gr[n, :, :, k].sum() / 12 for k in range(5)]
    for y in range(3):
        for x in range(4):
            ref[n, y, x] = max(0.0, sum(a[k] * fr[n, y, x, k] for k in range(5)))
assert np.allclose(grad_cam(fr, gr), ref), (
    "random features and gradients: each image uses its own alpha_k = mean_xy g_k")
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
assert np.allclose(c.mean(axis=(-2, -1)) + b_new, cams_r.mean(axis=(-2, -1)) + b_r), (
    "the predictions must not change: mean_xy(centred) + new bias = mean_xy(cams) + b")
### BEGIN HIDDEN TESTS
c_tr, _ = centre_on_baseline(train_r, train_r, b_r)
assert np.allclose(c_tr.mean(axis=0), 0.0), "the centred training CAMs must average to zero"
ego = rng.normal(size=(3, 5, 6))                 # a map common to every image
c2, b2 = centre_on_baseline(cams_r + ego, train_r + ego, b_r - ego.mean(axis=(-2, -1)))
assert np.allclose(c2, c) and np.allclose(b2, b_new), (
    "adding the same map to every CAM (and its mean to -b) must not change the centred result")
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
# *Hint.* Two checks you can do yourself: every $\sum_j S_j(x, y)$ is zero
# (the $q_j$ sum to one whatever $p$ is, so $\sum_j J_{ji} = 0$); and with
# $N = 2$, $M = 1$, $W_0 = \begin{pmatrix}1 & 0\\ 0 & 0\end{pmatrix}$,
# $q_{prev} = (1, 0)$ you get $q_0 = \sigma(p)$, so $J_{00} = \sigma(p)(1 - \sigma(p))$.

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
assert np.allclose(Sr.sum(axis=1), 0.0, atol=1e-6), (
    "sum_j S_j must vanish at every pixel: the q_j sum to one, so sum_j dq_j/dp_i = 0")
### BEGIN HIDDEN TESTS
import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402

from minimanc import engine  # noqa: E402

engine("jax")                               # turns on float64 in JAX
q0 = rng.dirichlet(np.ones(4))
Sr = q_saliency(q0, pr, Wr, cams_r)
for n in range(5):
    J = np.asarray(jax.jacobian(lambda pp: vagn.step(q0, pp, Wr, xp=jnp))(jnp.asarray(pr[n])))
    assert J.shape == (4, 3)
    ref = np.einsum("ji,ihw->jhw", J, cams_r[n])
    assert np.allclose(Sr[n], ref, atol=1e-6), (
        f"image {n}: S_j must equal sum_i (dq_j/dp_i) M_i with JAX's Jacobian of eq. 9")
### END HIDDEN TESTS

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
