# %% [markdown]
# # Chapter 6 — Exercises: class activation maps beyond the tutorial's head
#
# Module built in this chapter: `minimanc.cam` (paper section IV-A, eq. 7,
# and the saliency maps of the execution traces, section V). Replace each
# `raise NotImplementedError(...)` with your code and run the grade cell
# below it; `minimanc grade exercises/06_cam.ipynb` scores the notebook.
#
# The tutorial split the predicates of one head — conv → global average pooling →
# linear — into class activation maps, and found Grad-CAM equal to them. Here you
# carry the same ideas to heads and questions it did not show: a pooling that
# weighs the pixels (6.1, 6.3), where on the input a CAM pixel can look (6.2), the
# backward pass of the vAGN that turns predicate maps into q-state maps (6.4), a
# head with a hidden layer (6.5), and a head whose CAM points at the wrong object
# on purpose (6.6).
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
# ## Exercise 6.1 — CAMs for a pooling that weighs the pixels (transfer)
# Eq. 7 pools the features by their plain mean over the image. A variant weighs
# the positions with a fixed map $a(x, y) \ge 0$ (say, more weight on the road in
# front of the ego; $a$ need not sum to one):
#
# $$p_i = \sum_{x, y} a(x, y) \sum_k f_k(x, y)\, W_{ki} + b_i .$$
#
# Write `pooled_cams(features, a, w)`: the class activation maps of this head,
# shape `(B, M, H, W)`, for features `(B, H, W, K)`, the weighting `a` `(H, W)` and
# `w` `(K, M)`. As in the tutorial they must split each prediction over the pixels
# exactly — $\mathrm{mean}_{xy} M_i + b_i = p_i$ for every image — with each pixel's
# value depending only on that pixel's features, and linearly (no features, no map).
# Those three requirements leave one answer.
#
# <details><summary>Hint 1 (the idea)</summary>
#
# Write $p_i - b_i$ as a mean over the pixels of something that belongs to each pixel.
# </details>
#
# <details><summary>Hint 2 (the method)</summary>
#
# Multiply and divide by the number of pixels; check your maps on a 1 × 2 image by
# hand.
# </details>

# %% solution id=ex06_1 title="CAMs for a weighted pooling"
def pooled_cams(features, a, w):
    ### BEGIN SOLUTION
    f = np.asarray(features, float)
    H, W = f.shape[1:3]
    scaled = H * W * np.asarray(a, float)[None, :, :, None] * f   # pixel weight, times HW
    return np.einsum("bhwk,km->bmhw", scaled, np.asarray(w, float))
    ### END SOLUTION

# %% grade id=ex06_1_tests points=3
f1 = np.array([1.0, 3.0]).reshape(1, 1, 2, 1)          # one image, 1 x 2 pixels, K = 1
got = np.asarray(pooled_cams(f1, np.array([[0.25, 0.75]]), np.array([[2.0]])))
assert got.shape == (1, 1, 1, 2), (
    f"one image of 1 x 2 pixels, K = M = 1: expected maps of shape (1, 1, 1, 2); got "
    f"{got.shape}")
assert np.allclose(got[0, 0], [[1.0, 9.0]]), (
    f"f = [[1, 3]], a = [[0.25, 0.75]], w = [[2]] (p - b = 5): expected the map [[1, 9]]; "
    f"got {np.round(got[0, 0], 4).tolist()}")
f_r, w_r = rng.random((2, 4, 5, 3)), rng.normal(size=(3, 2))
ref = cam.class_activation_maps(f_r, w_r)
got = np.asarray(pooled_cams(f_r, np.full((4, 5), 1 / 20), w_r))
assert got.shape == ref.shape and np.allclose(got, ref), (
    f"uniform a = 1 / (H W) (eq. 7's plain mean): expected the tutorial's CAMs, e.g. image 0, "
    f"pixel (0, 0): {np.round(ref[0, :, 0, 0], 4).tolist()}; got "
    f"{np.round(got[0, :, 0, 0], 4).tolist() if got.shape == ref.shape else got.shape}")
### BEGIN HIDDEN TESTS
test_rng = np.random.default_rng(610)  # the tests' own draws, not the notebook's rng
fr, wr = test_rng.normal(size=(3, 6, 4, 5)), test_rng.normal(size=(5, 2))
ar, br = test_rng.random((6, 4)) * 3.0, test_rng.normal(size=2)
p_ref = np.einsum("bhwk,hw,km->bm", fr, ar, wr) + br            # the head, written out
a_sum = ar.sum()
bumped = fr.copy()
bumped[1, 2, 3] += 1.0                                           # one pixel of image 1
got = np.asarray(pooled_cams(fr, ar, wr))
assert got.shape == (3, 2, 6, 4), f"B = 3, M = 2, 6 x 4: expected (3, 2, 6, 4); got {got.shape}"
assert np.allclose(got.mean(axis=(2, 3)) + br, p_ref), (
    f"random features, a summing to {a_sum:.3f}: expected mean_xy M + b = p = "
    f"{np.round(p_ref[0], 4).tolist()} for image 0; got "
    f"{np.round(got.mean(axis=(2, 3))[0] + br, 4).tolist()}")
moved = np.abs(np.asarray(pooled_cams(bumped, ar, wr)) - got).sum(axis=1) > 1e-12
assert moved[1, 2, 3] and moved.sum() == 1, (
    f"features changed at pixel (2, 3) of image 1 only: expected the maps to change there "
    f"only; they changed at {np.argwhere(moved).tolist()}")
zero = np.asarray(pooled_cams(np.zeros((1, 6, 4, 5)), ar, wr))
assert np.allclose(zero, 0.0), f"no features: expected zero maps; got up to {np.abs(zero).max()}"
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 6.2 — where on the input can a CAM pixel look? (derivation)
# The tutorial's CAMs live on the 16 × 16 feature grid and were upsampled to 32 × 32
# to be read against the objects' boxes. How precisely can a CAM pixel localise
# anything? Feature pixel $(r, c)$ depends only on a window of input pixels, its
# **receptive field**. Write `receptive_box(r, c, convs, image_shape)`: for a stack
# of convolutions `convs = [(kernel, stride, padding), ...]` (input first, applied as
# `layers.conv` applies them: square kernels, zero padding on every side), return the
# box `(r0, c0, r1, c1)` of the input pixels that can change feature pixel `(r, c)`,
# rows `r0 ≤ row < r1` and columns `c0 ≤ col < c1`, clipped to the image
# `image_shape = (H, W)`. Kernels are at least as large as their strides.
# (Take care at the borders: a layer may drop its last rows.)
#
# <details><summary>Hint 1 (the idea)</summary>
#
# Follow one row index backwards, layer by layer: which rows of the layer below does
# one output row read? A window of windows is a window.
# </details>
#
# <details><summary>Hint 2 (the method)</summary>
#
# Walk backwards from the feature pixel, one layer at a time, carrying a window of
# rows (and one of columns). Padding is not a pixel: at every layer, keep the window
# inside that layer — whose size you get by walking forwards first.
# </details>

# %% solution id=ex06_2 title="The receptive field of a CAM pixel"
def receptive_box(r, c, convs, image_shape):
    ### BEGIN SOLUTION
    sizes = [tuple(image_shape)]                     # each layer's (rows, cols), input first
    for kernel, stride, padding in convs:
        sizes.append(tuple((n + 2 * padding - kernel) // stride + 1 for n in sizes[-1]))
    box = [(r, r + 1), (c, c + 1)]                   # half-open windows, feature layer
    for (kernel, stride, padding), below in zip(convs[::-1], sizes[-2::-1]):
        # an output index i reads the rows stride * i - padding ... + kernel - 1 below,
        # of which only those inside the layer exist (the rest is padding)
        box = [(max(stride * lo - padding, 0), min(stride * (hi - 1) - padding + kernel, n))
               for (lo, hi), n in zip(box, below)]
    (r0, r1), (c0, c1) = box
    return r0, c0, r1, c1
    ### END SOLUTION

# %% grade id=ex06_2_tests points=3
EXTRACTOR = [(3, 1, 1), (3, 2, 1)]   # the tutorial's cam.init_extractor: 32 x 32 -> 16 x 16
got = tuple(int(v) for v in receptive_box(8, 5, EXTRACTOR, (32, 32)))
assert got == (14, 8, 19, 13), (
    f"the tutorial's extractor, feature pixel (8, 5): expected the input box (14, 8, 19, 13); "
    f"got {got}")
got = tuple(int(v) for v in receptive_box(0, 15, EXTRACTOR, (32, 32)))
assert got == (0, 28, 3, 32), (
    f"the tutorial's extractor, feature pixel (0, 15), at the image's edge: expected "
    f"(0, 28, 3, 32); got {got}")
### BEGIN HIDDEN TESTS
from minimanc import engine, layers  # noqa: E402


def reads(n_in, kernel, stride, padding):
    """0/1 matrix (n_out, n_in): which input indices each output index of one conv reads."""
    n_out = (n_in + 2 * padding - kernel) // stride + 1
    m = np.zeros((n_out, n_in))
    for i in range(n_out):
        lo = stride * i - padding
        m[i, max(lo, 0):max(min(lo + kernel, n_in), 0)] = 1.0
    return m


def support_box(r, c, convs, shape):
    """The input rows and columns that reach feature pixel (r, c): the product of the
    layers' 0/1 matrices along each axis (a conv stack reads rows and columns alike)."""
    box = []
    for index, n in zip((r, c), shape):
        chain = np.eye(n)
        for kernel, stride, padding in convs:
            chain = reads(chain.shape[0], kernel, stride, padding) @ chain
        hit = np.nonzero(chain[index] > 0)[0]
        box.append((int(hit.min()), int(hit.max()) + 1))
    (r0, r1), (c0, c1) = box
    return r0, c0, r1, c1


# one case against the library's own convolution: where the gradient of the pixel is not 0
eng = engine("numpy")
stack = [{"w": np.random.default_rng(620).normal(size=(3, 3, 1, 1)), "b": np.zeros(1)}
         for _ in range(2)]


def pixel(x):
    h = layers.conv(stack[0], x, eng.nn, stride=1, padding=1)
    return eng.xp.sum(layers.conv(stack[1], h, eng.nn, stride=2, padding=1)[0, 7, 0])


grad = np.abs(np.asarray(eng.grad(pixel)(np.zeros((1, 16, 12, 1)))))[0, :, :, 0]
rows, cols = np.nonzero(grad > 1e-12)
want = (int(rows.min()), int(cols.min()), int(rows.max()) + 1, int(cols.max()) + 1)
assert want == support_box(7, 0, [(3, 1, 1), (3, 2, 1)], (16, 12))   # the oracle itself
got = tuple(int(v) for v in receptive_box(7, 0, [(3, 1, 1), (3, 2, 1)], (16, 12)))
assert got == want, (
    f"the tutorial's extractor on a 16 x 12 image, feature pixel (7, 0): expected the box "
    f"{want} (where the gradient of that pixel is not zero); got {got}")
cases = [([(3, 1, 1), (3, 2, 1)], (32, 32), (7, 9)),
         ([(5, 2, 2), (3, 1, 0), (3, 2, 1)], (40, 36), (3, 4)),
         ([(3, 2, 1), (3, 2, 1), (3, 2, 1)], (64, 64), (4, 2)),
         ([(4, 2, 1), (2, 2, 0), (3, 1, 1)], (30, 30), (0, 6)),
         ([(3, 2, 0), (5, 1, 2)], (25, 29), (11, 0)),
         ([(7, 3, 3), (3, 2, 1)], (50, 41), (8, 6))]
for convs, shape, (r, c) in cases:
    want = support_box(r, c, convs, shape)
    got = tuple(int(v) for v in receptive_box(r, c, convs, shape))
    assert got == want, (
        f"convs {convs}, image {shape}, feature pixel ({r}, {c}): expected the box {want} "
        f"(the input pixels that reach it); got {got}")
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 6.3 — Grad-CAM of the weighted pooling (derivation)
# The tutorial showed that Grad-CAM — weigh each feature map $f_k$ by the mean over the
# pixels of $\partial p_i / \partial f_k(x, y)$, sum, keep the positive part — equals
# the CAM for conv → GAP → linear, up to a positive factor. Work it out for the head
# of 6.1: write `weighted_grad_cam(features, a, w, i)`, the Grad-CAM of predicate `i`,
# shape `(B, H, W)`, from the derivative you work out by hand (no autodiff). Then
# compare it with your maps of 6.1: where can the two disagree?
#
# <details><summary>Hint 1 (the idea)</summary>
#
# $p_i$ is linear in every $f_k(x, y)$: its derivative is a number per pixel and
# channel. Which numbers does averaging over the pixels keep?
# </details>
#
# <details><summary>Hint 2 (the method)</summary>
#
# Differentiate the sum of 6.1 with respect to one $f_k(x, y)$, average over $(x, y)$,
# and only then form the weighted sum of the feature maps.
# </details>

# %% solution id=ex06_3 title="Grad-CAM of the weighted pooling" forbids="minimanc.cam.grad_cam"
def weighted_grad_cam(features, a, w, i):
    ### BEGIN SOLUTION
    f = np.asarray(features, float)
    H, W = f.shape[1:3]
    alpha = np.asarray(a, float).sum() / (H * W) * np.asarray(w, float)[:, i]   # (K,)
    return np.maximum(f @ alpha, 0.0)
    ### END SOLUTION

# %% grade id=ex06_3_tests points=3
f3 = np.zeros((1, 1, 2, 2))
f3[0, 0, 0] = [1.0, 0.0]
f3[0, 0, 1] = [0.0, 1.0]
a3 = np.array([[0.0, 4.0]])              # only the right pixel is pooled
got = np.asarray(weighted_grad_cam(f3, a3, np.array([[3.0], [-1.0]]), 0))
assert got.shape == (1, 1, 2), f"B = 1, 1 x 2 pixels: expected shape (1, 1, 2); got {got.shape}"
assert np.allclose(got, [[[6.0, 0.0]]]), (
    f"a = [[0, 4]], pixel features (1, 0) and (0, 1), w = (3, -1): expected Grad-CAM "
    f"[[6, 0]]; got {np.round(got, 4).tolist()}")
### BEGIN HIDDEN TESTS
test_rng = np.random.default_rng(630)  # the tests' own draws, not the notebook's rng
fr, wr = test_rng.normal(size=(3, 5, 4, 6)), test_rng.normal(size=(6, 3))
ar = test_rng.random((5, 4)) * 2.0
a_sum, refs = ar.sum(), []
for i in range(3):
    ref = []
    for n in range(3):   # Grad-CAM by its definition; p is linear, so a central difference
        g = np.zeros((5, 4, 6))                              # of it is exact to rounding
        for idx in np.ndindex(5, 4, 6):
            e = np.zeros((5, 4, 6))
            e[idx] = 1e-3
            g[idx] = (np.einsum("hwk,hw,k->", fr[n] + e, ar, wr[:, i])
                      - np.einsum("hwk,hw,k->", fr[n] - e, ar, wr[:, i])) / 2e-3
        ref.append(np.maximum(np.einsum("hwk,k->hw", fr[n], g.mean(axis=(0, 1))), 0.0))
    refs.append(np.stack(ref))
for i, ref in enumerate(refs):
    got = np.asarray(weighted_grad_cam(fr, ar, wr, i))
    assert got.shape == ref.shape and np.allclose(got, ref, atol=1e-8), (
        f"random features, a summing to {a_sum:.3f}, predicate {i}: expected image 0 = "
        f"{np.round(ref[0], 3).tolist()}; got "
        f"{np.round(got[0], 3).tolist() if got.shape == ref.shape else got.shape}")
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 6.4 — the backward pass of the vAGN step (derivation)
# The tutorial carried the predicate maps to the q-states through
# $J_{ji} = \partial q_j / \partial p_i$ and let `cam.explain` compute $J$. Derive it.
# One vAGN step (chapter 5, eqs. 8–9) is
#
# $$A = \sum_i p_i W_i,\qquad T = \mathrm{colsoftmax}\big(\mathrm{ReLU}(A)\big),\qquad
#   q = T\, q_{prev},$$
#
# the softmax taken down each column of $T$ (every column sums to one).
#
# 1. `vagn_jacobian(q_prev, p, W)`: $J$ of shape `(B, N, M)` for `q_prev` `(B, N)`,
#    predicates `p` `(B, M)` and weights `W` `(M, N, N)`, **in closed form** — no
#    finite differences, no autodiff: the tests compare it with an exact Jacobian to
#    1e-11, closer than a finite difference gets. Where $A$ is exactly 0 the ReLU
#    counts as inactive. (3 points)
# 2. `q_grad_cam(features, w, b, q_prev, W, j)`: the Grad-CAM of q-state $j$ (the
#    recipe of 6.3, with $q_j$ in place of $p_i$) for the tutorial's head, linear
#    predicates $p = \mathrm{gap}(f)\,w + b$ feeding one vAGN step; shape `(B, H, W)`.
#    (2 points)
#
# `cam.vagn_jacobian`, `cam.explain` and `models.saliency` are switched off while this
# exercise is graded.
#
# <details><summary>Hint 1 (the idea)</summary>
#
# Chain rule in three links: how one entry of $T$ moves with the entries of its own
# column, how the ReLU passes a change of $A$ on, and how $A$ moves with $p_i$. Only
# column $j$ of $T$ multiplies $q_{prev, j}$.
# </details>
#
# <details><summary>Hint 2 (two checks you can do yourself)</summary>
#
# Every column of $J$ sums to zero (the $q_j$ sum to one whatever $p$ is); and with
# $N = 2$, $M = 1$, $W_0 = \begin{pmatrix}1 & 0\\ 0 & 0\end{pmatrix}$,
# $q_{prev} = (1, 0)$ and $p > 0$, $q_0$ is the logistic sigmoid of $p$. Compare with
# a central difference of `vagn.step` at a few random points while you work.
# </details>

# %% solution id=ex06_4 title="The backward pass of the vAGN step" forbids="minimanc.cam.vagn_jacobian,minimanc.cam.explain,minimanc.models.saliency"  # noqa: E501
def vagn_jacobian(q_prev, p, W):
    ### BEGIN SOLUTION
    q_prev, p, W = (np.asarray(x, float) for x in (q_prev, p, W))
    A = np.einsum("bm,mij->bij", p, W)                          # eq. 8
    R = np.maximum(A, 0.0)
    E = np.exp(R - R.max(axis=1, keepdims=True))
    T = E / E.sum(axis=1, keepdims=True)                         # eq. 9, columns sum to one
    D = (A > 0)[:, None] * W[None]                               # dR/dp_m, (B, M, N, N)
    # dT_aj/dp_m = T_aj (D_m,aj - sum_c T_cj D_m,cj): the softmax's Jacobian per column
    dT = T[:, None] * (D - np.einsum("bcj,bmcj->bmj", T, D)[:, :, None, :])
    return np.einsum("bmaj,bj->bam", dT, q_prev)
    ### END SOLUTION


def q_grad_cam(features, w, b, q_prev, W, j):
    ### BEGIN SOLUTION
    f = np.asarray(features, float)
    p = f.mean(axis=(1, 2)) @ w + b
    J = vagn_jacobian(q_prev, p, W)                              # (B, N, M)
    alpha = J[:, j] @ np.asarray(w, float).T / (f.shape[1] * f.shape[2])  # (B, K)
    return np.maximum(np.einsum("bhwk,bk->bhw", f, alpha), 0.0)
    ### END SOLUTION

# %% grade id=ex06_4_jacobian_tests points=3
W4 = np.zeros((1, 2, 2))
W4[0, 0, 0] = 1.0
J4 = np.asarray(vagn_jacobian(np.array([[1.0, 0.0]]), np.array([[np.log(3.0)]]), W4))
assert J4.shape == (1, 2, 1), f"B = 1, N = 2, M = 1: expected J of shape (1, 2, 1); got {J4.shape}"
assert np.allclose(J4[0, :, 0], [0.1875, -0.1875], rtol=0, atol=1e-12), (
    f"N = 2, M = 1, W_0 = [[1, 0], [0, 0]], q_prev = (1, 0), p = log 3: expected "
    f"J = [0.1875, -0.1875] to 1e-12 (closer than a finite difference gets); got "
    f"{J4[0, :, 0].tolist()}")
Wr, pr = rng.normal(size=(3, 4, 4)), rng.normal(size=(5, 3))
Jr = np.asarray(vagn_jacobian(vagn.uniform_state(4)[None].repeat(5, 0), pr, Wr))
worst = np.abs(Jr.sum(axis=1)).max()
assert Jr.shape == (5, 4, 3) and worst < 1e-12, (
    f"random W (3, 4, 4), 5 images: expected each column of J to sum to zero (the q_j sum to "
    f"one); got shape {Jr.shape}, column sums up to {worst:.3g}")
### BEGIN HIDDEN TESTS
from minimanc import engine  # noqa: E402, F811

eng = engine("numpy")
xp = eng.xp
test_rng = np.random.default_rng(640)  # the tests' own draws, not the notebook's rng
M4, N4 = 3, 5
Wh = test_rng.normal(size=(M4, N4, N4)) * 2.0
ph, qh = test_rng.normal(size=(6, M4)), test_rng.dirichlet(np.ones(N4), size=6)


def q_of(q0, pp, j):    # eqs. 8-9 written out, state j, for the NumPy engine's autodiff
    R = xp.maximum(xp.einsum("m,mij->ij", pp, Wh), 0.0)
    E = xp.exp(R - xp.max(R, axis=0, keepdims=True))
    return xp.matmul(E / xp.sum(E, axis=0, keepdims=True), q0)[j]


refs = [np.stack([np.asarray(eng.grad(lambda pp, n=n, j=j: q_of(qh[n], pp, j))(ph[n]))
                  for j in range(N4)]) for n in range(6)]
got = np.asarray(vagn_jacobian(qh, ph, Wh))
for n, ref in enumerate(refs):
    assert got.shape == (6, N4, M4) and np.allclose(got[n], ref, rtol=1e-11, atol=1e-12), (
        f"image {n}, random W, p and q_prev: expected J = {np.round(ref, 6).tolist()} (to "
        f"1e-11, closer than a finite difference); got "
        f"{np.round(got[n], 6).tolist() if got.shape == (6, N4, M4) else got.shape}")
Wk = np.zeros((2, 2, 2))
Wk[0, 0, 0], Wk[1, 0, 0] = 1.0, 1.0                  # A_00 = p_0 + p_1 = 0 exactly: a kink
Wk[0, 1, 1] = 2.0
got = np.asarray(vagn_jacobian(np.array([[0.5, 0.5]]), np.array([[1.0, -1.0]]), Wk))[0]
s = np.exp(2.0) / (1.0 + np.exp(2.0))                # column 1: softmax of (0, 2)
want = np.array([[-0.5 * s * (1 - s) * 2.0, 0.0], [0.5 * s * (1 - s) * 2.0, 0.0]])
assert np.allclose(got, want, atol=1e-12), (
    f"A = 0 exactly in one entry (the ReLU counts as inactive there): expected "
    f"{np.round(want, 6).tolist()}; got {np.round(got, 6).tolist()}")
### END HIDDEN TESTS

# %% grade id=ex06_4_gradcam_tests points=2
f4 = rng.random((2, 3, 4, 5))
w4, b4 = rng.normal(size=(5, 3)), rng.normal(size=3)
W4r, q4 = rng.normal(size=(3, 4, 4)), vagn.uniform_state(4)[None].repeat(2, 0)
g0, g1 = (np.asarray(q_grad_cam(f4, w4, b4, q4, W4r, j)) for j in (0, 1))
assert g0.shape == (2, 3, 4) and np.all(g0 >= 0), (
    f"2 images of 3 x 4: expected a non-negative map of shape (2, 3, 4); got shape "
    f"{g0.shape}, smallest value {g0.min():.3g}")
W2 = np.zeros((1, 2, 2))
W2[0, 1, :] = 1.0                                    # the predicate sends q to state 1
f2 = np.zeros((1, 1, 2, 1))
f2[0, 0] = [[2.0], [0.0]]
got = np.asarray(q_grad_cam(f2, np.array([[1.0]]), np.array([0.0]),
                            np.array([[0.5, 0.5]]), W2, 1))
assert np.allclose(got, [[[0.196612, 0.0]]], atol=1e-6), (
    f"N = 2, one predicate p = gap(f) = 1 sending q to state 1, features [[2], [0]]: expected "
    f"the Grad-CAM of q_1 [[0.196612, 0]]; got {np.round(got, 6).tolist()}")
### BEGIN HIDDEN TESTS
from minimanc import engine  # noqa: E402, F811

eng = engine("numpy")
xp = eng.xp
test_rng = np.random.default_rng(641)  # the tests' own draws, not the notebook's rng
fh = test_rng.random((3, 4, 5, 6))
wh, bh = test_rng.normal(size=(6, 3)), test_rng.normal(size=3)
Wg, qg = test_rng.normal(size=(3, 4, 4)) * 2.0, test_rng.dirichlet(np.ones(4), size=3)


def qj_of(x, q0, j):   # linear predicates of the features, then eqs. 8-9, written out
    pp = xp.matmul(xp.mean(x, axis=(0, 1)), wh) + bh
    R = xp.maximum(xp.einsum("m,mij->ij", pp, Wg), 0.0)
    E = xp.exp(R - xp.max(R, axis=0, keepdims=True))
    return xp.matmul(E / xp.sum(E, axis=0, keepdims=True), q0)[j]


refs = {(j, n): np.maximum(np.einsum("hwk,k->hw", fh[n], np.asarray(
    eng.grad(qj_of)(fh[n], qg[n], j)).mean(axis=(0, 1))), 0.0) for j in range(4) for n in range(3)}
for j in range(4):
    got = np.asarray(q_grad_cam(fh, wh, bh, qg, Wg, j))
    for n in range(3):
        ref = refs[j, n]
        assert got.shape == (3, 4, 5) and np.allclose(got[n], ref, atol=1e-10), (
            f"image {n}, q-state {j}: expected the Grad-CAM {np.round(ref, 5).tolist()}; got "
            f"{np.round(got[n], 5).tolist() if got.shape == (3, 4, 5) else got.shape}")
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 6.5 — CAMs for a head with a hidden ReLU layer (derivation)
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
# For one image, a unit that is on passes its input unchanged and a unit that is
# off outputs 0: write that image's head without the ReLU, then read off what
# multiplies $\mathrm{gap}(f)$ and what does not. The batch axis now sits on the
# weights too (`np.einsum` with three operands).
# </details>

# %% solution id=ex06_5 title="CAMs for a head with a hidden ReLU layer"
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
    """The head of 6.5: p = ReLU(gap(f) U + b1) V + c, shape (B, M)."""
    return np.maximum(np.asarray(features).mean(axis=(1, 2)) @ U + b1, 0.0) @ V + c

# %% grade id=ex06_5_head_tests points=2
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
g = fr.mean(axis=(1, 2))
# the Jacobian of the head at each image, by central differences, and its value
jacs = [np.stack([(mlp_head(fr[n:n + 1] + e, Ur, b1r, Vr, cr)
                   - mlp_head(fr[n:n + 1] - e, Ur, b1r, Vr, cr))[0] / 2e-6
                  for e in 1e-6 * np.eye(3)]) for n in range(6)]
p_all = mlp_head(fr, Ur, b1r, Vr, cr)
w, b = (np.asarray(x) for x in effective_head(fr, Ur, b1r, Vr, cr))
assert w.shape == (6, 3, 2) and b.shape == (6, 2), (
    f"B = 6, K = 3, M = 2: expected (6, 3, 2) and (6, 2); got {w.shape}, {b.shape}")
for n, jac in enumerate(jacs):
    assert np.allclose(w[n], jac, atol=1e-6), (
        f"image {n}: expected w_eff = dp/d gap(f) = {np.round(jac, 4).tolist()}; "
        f"got {np.round(w[n], 4).tolist()}")
    p_n = p_all[n]
    assert np.allclose(g[n] @ w[n] + b[n], p_n), (
        f"image {n}: expected gap(f) w_eff + b_eff = p = {np.round(p_n, 4).tolist()}; "
        f"got {np.round(g[n] @ w[n] + b[n], 4).tolist()}")
### END HIDDEN TESTS

# %% grade id=ex06_5_cams_tests points=2
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
cases = []
for n in range(5):   # the tests' own per-image weights: the units that are on, written out
    z = fr[n].mean(axis=(0, 1)) @ Ur + b1r
    w_n = sum(np.outer(Ur[:, d], Vr[d]) for d in range(6) if z[d] > 0)
    b_n = sum(b1r[d] * Vr[d] for d in range(6) if z[d] > 0) + cr
    cases.append((np.einsum("hwk,km->mhw", fr[n], w_n), b_n,
                  mlp_head(fr[n:n + 1], Ur, b1r, Vr, cr)[0]))
got = np.asarray(mlp_cams(fr, Ur, b1r, Vr, cr))
assert got.shape == (5, 2, 3, 4), f"B = 5, M = 2, 3 x 4: expected (5, 2, 3, 4); got {got.shape}"
for n, (ref, b_n, p_n) in enumerate(cases):
    assert np.allclose(got[n], ref), (
        f"image {n}: expected the CAMs sum_k w_eff[k, i] f_k with its own active units; "
        f"largest difference {np.abs(got[n] - ref).max():.3g}")
    assert np.allclose(got[n].mean(axis=(1, 2)) + b_n, p_n), (
        f"image {n}: expected mean_xy M + b_eff = p = {np.round(p_n, 4).tolist()}; "
        f"got {np.round(got[n].mean(axis=(1, 2)) + b_n, 4).tolist()}")
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 6.6 — open experiment: a head that looks at the ego (design)
# The tutorial's CNN put part of its pedestrian CAM on the ego vehicle, and the
# tutorial called the map *ambiguous*. Make that ambiguity yourself. Below are scenes
# with a road, the ego (red, always at the same place) and, in most, a vehicle
# (yellow), and the hand-made features of "Putting it together": channel 0
# fires on yellow, channel 1 on red. The head `W_VEH = [[2], [0]]`, `B_VEH = [0]`
# predicts *vehicle present* and its CAM sits on the vehicle.
#
# Write `ego_head()` returning `(w, b)`, shapes `(2, 1)` and `(1,)`: a head that
# makes **the same predictions** as `W_VEH`, `B_VEH` on every such scene (to
# 1e-9; the tests draw scenes of their own), but whose raw CAM **peaks on the
# ego** in every scene. Then centre your head's maps on the tutorial's data-set
# baseline (subtract their mean over the scenes) and look where they peak.
# Checked automatically: the predictions, the raw peaks on the ego, and the
# centred peaks back on the vehicle.
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

# %% solution id=ex06_6 title="Open experiment: a head whose CAM looks at the ego"
def ego_head():
    ### BEGIN SOLUTION
    # the ego's red mass is the same in every scene (24 of 1024 pixels): any weight on
    # the red channel adds a constant to p, which the bias takes back
    w_red = 5.0                                   # above the yellow weight 2: the ego wins
    return np.array([[2.0], [w_red]]), np.array([-w_red * 24 / 1024])
    ### END SOLUTION

# %% grade id=ex06_6_tests points=3
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
# **Written question (6.6).** Your head and `W_VEH` make the same predictions
# on every scene; their raw CAMs disagree completely. Which one is "right", and
# what does that say about reading a raw CAM as the answer to "where does the
# network look"? Why does the tutorial's data-set baseline repair your head here,
# and describe a data set on which it would *not* (where would the baseline
# fail to tell the ego from the object)?

# %% [markdown] answer id=ex06_6_w title="Which CAM is right" points=2
# ### BEGIN SOLUTION
# Neither is more right: the two heads are the same predictor on this data,
# because the ego's red mass is identical in every scene, so w_red·(red mass) is
# a constant that the bias cancels. The CAM splits p over pixels, but only up to
# a map common to all images (the tutorial, section 5), so a raw CAM answers "where is the evidence
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
# One scene of 6.6, with maps made by **your** functions: the vehicle head's CAM
# (your `pooled_cams` with the plain mean, drawn over the library's when yours
# raises), your `weighted_grad_cam` for the same head pooled over the rows below the
# ego only — where this scene's vehicle is not, so the head does not see it — your
# `ego_head`'s raw CAM (it should sit on the ego) and the same map centred on the mean
# over the 40 scenes (back on the vehicle). A function that raises is named in its
# panel's title.

# %%
k_fig = next(k for k, (_, box) in enumerate(scenes) if box is not None)
PLAIN = np.full((32, 32), 1 / 1024)            # eq. 7's mean as a weighting
BELOW = np.zeros((32, 32))
BELOW[30:] = 1.0                               # the two rows below the ego


def ego_cams():
    """CAMs (40, 32, 32) of your ego_head over the 40 scenes."""
    w, _ = ego_head()
    return np.asarray(pooled_cams(F_ego, PLAIN, np.asarray(w)))[:, 0]


print("the vehicle in this scene:", scenes[k_fig][1])
plot_overlay_attempts(X_ego[k_fig], [
    ("vehicle CAM", lambda: pooled_cams(F_ego[k_fig:k_fig + 1], PLAIN, W_VEH)[0, 0],
     cam.class_activation_maps(F_ego[k_fig:k_fig + 1], W_VEH)[0, 0]),
    ("Grad-CAM, rows 30-31", lambda: weighted_grad_cam(F_ego[k_fig:k_fig + 1], BELOW, W_VEH,
                                                       0)[0], None),
    ("ego head, raw", lambda: ego_cams()[k_fig], None),
    ("ego head, centred", lambda: (ego_cams() - ego_cams().mean(axis=0))[k_fig], None)])
plt.show()
