# %% [markdown]
# # Chapter 2 — Exercises: convolution, pooling, initialisation and optimisers
#
# Modules built in this chapter: `minimanc.layers`, `minimanc.optim` and the
# primitives of `minimanc.autodiff.nn` (paper eq. 7: conv → GAP → linear).
# You will write the convolution forward and backward, global average pooling,
# Adam, He initialisation, SGD with momentum, the index computation of im2col
# and the gradient of the softmax cross-entropy.
# Replace each `raise NotImplementedError(...)` with your code and run the
# grade cell below it; `minimanc grade exercises/02_training.ipynb` scores the
# notebook. Plain NumPy is enough everywhere; loops are fine, speed is not graded.
#
# Conventions: images NHWC `(N, H, W, C)`, kernels HWIO `(kh, kw, C, O)`,
# `padding` zero pixels on each side, output size `(H + 2 padding - kh) // stride + 1`.

# %%
import math

import numpy as np

from minimanc import engine, layers, optim
from minimanc.autodiff import nn

rng = np.random.default_rng(0)

# %% [markdown]
# ## Exercise 2.1 — the convolution, forward
# Return `y` of shape `(N, Ho, Wo, O)` with
# $y[n,i,j,o] = b[o] + \sum_{u,v,c} x_\text{pad}[n, s i + u, s j + v, c]\, w[u,v,c,o]$.
# `np.pad` builds $x_\text{pad}$; a loop over output pixels with
# `np.tensordot(window, w, axes=3)`, or an im2col with one matrix product, both work.

# %% solution id=ex02_1 title="conv2d forward" forbids="minimanc.autodiff.nn.conv2d,minimanc.layers.conv2d,minimanc.autodiff.nn._conv_fwd,minimanc.autodiff.nn._conv_bwd"  # noqa: E501
def conv2d_forward(x, w, b, stride=1, padding=0):
    ### BEGIN SOLUTION
    n, h, wd, c = x.shape
    kh, kw, _, o = w.shape
    xpad = np.pad(x, ((0, 0), (padding, padding), (padding, padding), (0, 0)))
    ho = (h + 2 * padding - kh) // stride + 1
    wo = (wd + 2 * padding - kw) // stride + 1
    y = np.empty((n, ho, wo, o))
    for i in range(ho):
        for j in range(wo):
            window = xpad[:, stride * i:stride * i + kh, stride * j:stride * j + kw, :]
            y[:, i, j, :] = np.tensordot(window, w, axes=3) + b
    return y
    ### END SOLUTION

# %% grade id=ex02_1_tests points=3
def slow_conv(x, w, b, stride, padding):
    """The definition, one output element at a time (an independent reference)."""
    n, h, wd, c = x.shape
    kh, kw, _, o = w.shape
    ho, wo = (h + 2 * padding - kh) // stride + 1, (wd + 2 * padding - kw) // stride + 1
    y = np.zeros((n, ho, wo, o))
    for i in range(ho):
        for j in range(wo):
            for u in range(kh):
                for v in range(kw):
                    r, q = stride * i + u - padding, stride * j + v - padding
                    if 0 <= r < h and 0 <= q < wd:  # outside: a zero of the padding
                        y[:, i, j, :] += x[:, r, q, :] @ w[u, v]
    return y + (0.0 if b is None else b)


x = rng.standard_normal((2, 6, 5, 3))
w = rng.standard_normal((3, 3, 3, 4))
b = rng.standard_normal(4)
y = conv2d_forward(x, w, b, stride=1, padding=0)
assert y.shape == (2, 4, 3, 4), f"(N, Ho, Wo, O) = (2, 4, 3, 4) expected, got {y.shape}"
assert np.allclose(y[0, 0, 0], np.tensordot(x[0, :3, :3], w, axes=3) + b), \
    "y[0, 0, 0] is the top-left 3x3 window contracted with w, plus b"
assert np.allclose(y, slow_conv(x, w, b, stride=1, padding=0)), "stride 1, no padding"
assert np.allclose(conv2d_forward(x, w, b, 2, 1), slow_conv(x, w, b, 2, 1)), "stride 2, padding 1"
### BEGIN HIDDEN TESTS
for kh, kw, s, p in [(1, 1, 1, 0), (2, 3, 2, 1), (3, 3, 3, 2), (4, 2, 1, 1)]:
    xh = rng.standard_normal((3, 7, 8, 2))
    wh = rng.standard_normal((kh, kw, 2, 5))
    bh = rng.standard_normal(5)
    assert np.allclose(conv2d_forward(xh, wh, bh, s, p), slow_conv(xh, wh, bh, s, p)), \
        f"kernel ({kh}, {kw}), stride {s}, padding {p}: the definition"
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 2.2 — the convolution, backward
# Given the cotangent `g` of the output (shape `(N, Ho, Wo, O)`), return
# `(dx, dw, db)`, the cotangents of `x`, `w` and `b`. Think of the forward pass
# as one matrix product per kernel offset $(u, v)$: the strided slice
# `xpad[:, u::s, v::s, :]` (cut to `Ho × Wo`) times `w[u, v]`. Each offset
# contributes to `dw[u, v]` and **adds** `g @ w[u, v].T` back onto the
# input pixels it read. Remember to drop the padding from `dx`.

# %% solution id=ex02_2 title="conv2d backward" forbids="minimanc.autodiff.nn.conv2d,minimanc.layers.conv2d,minimanc.autodiff.nn._conv_fwd,minimanc.autodiff.nn._conv_bwd"  # noqa: E501
def conv2d_backward(x, w, g, stride=1, padding=0):
    ### BEGIN SOLUTION
    xpad = np.pad(x, ((0, 0), (padding, padding), (padding, padding), (0, 0)))
    dxpad, dw = np.zeros_like(xpad), np.zeros_like(w)
    ho, wo = g.shape[1:3]
    for u in range(w.shape[0]):
        for v in range(w.shape[1]):
            rows = slice(u, u + stride * (ho - 1) + 1, stride)
            cols = slice(v, v + stride * (wo - 1) + 1, stride)
            dw[u, v] = np.einsum("nhwc,nhwo->co", xpad[:, rows, cols, :], g)
            dxpad[:, rows, cols, :] += g @ w[u, v].T
    dx = dxpad[:, padding:padding + x.shape[1], padding:padding + x.shape[2], :]
    return dx, dw, g.sum(axis=(0, 1, 2))
    ### END SOLUTION

# %% grade id=ex02_2_tests points=3
def slow_conv_vjp(x, w, g, stride, padding):
    """Reference cotangents from the definition: each output element
    y[n, i, j, o] += x[n, r, q, c] w[u, v, c, o] sends g back to both factors."""
    dx, dw = np.zeros_like(x), np.zeros_like(w)
    h, wd = x.shape[1:3]
    for i in range(g.shape[1]):
        for j in range(g.shape[2]):
            for u in range(w.shape[0]):
                for v in range(w.shape[1]):
                    r, q = stride * i + u - padding, stride * j + v - padding
                    if 0 <= r < h and 0 <= q < wd:
                        dx[:, r, q, :] += g[:, i, j, :] @ w[u, v].T
                        dw[u, v] += x[:, r, q, :].T @ g[:, i, j, :]
    return dx, dw, g.sum(axis=(0, 1, 2))


eng = engine("numpy")
xp = eng.xp
x = rng.standard_normal((2, 5, 6, 3))
w = rng.standard_normal((3, 3, 3, 2))
b = rng.standard_normal(2)
g = rng.standard_normal((2, 3, 3, 2))  # (5 + 2 - 3) // 2 + 1 = 3, (6 + 2 - 3) // 2 + 1 = 3
dx, dw, db = conv2d_backward(x, w, g, stride=2, padding=1)
assert dx.shape == x.shape and dw.shape == w.shape and db.shape == b.shape, \
    "dx, dw, db have the shapes of x, w, b"
ref = slow_conv_vjp(x, w, g, 2, 1)
assert np.allclose(db, ref[2]), "db: sum of g over batch and pixels"
assert np.allclose(dw, ref[1]), "dw[u, v] = sum over windows of x_window^T g"
assert np.allclose(dx, ref[0]), "dx: add back onto the pixels each window read"
### BEGIN HIDDEN TESTS
for kh, kw, s, p in [(1, 1, 1, 0), (2, 3, 3, 2), (3, 3, 1, 1)]:
    xh = rng.standard_normal((2, 7, 6, 2))
    wh = rng.standard_normal((kh, kw, 2, 3))
    ho, wo = (7 + 2 * p - kh) // s + 1, (6 + 2 * p - kw) // s + 1
    gh = rng.standard_normal((2, ho, wo, 3))
    got = conv2d_backward(xh, wh, gh, s, p)
    rh = slow_conv_vjp(xh, wh, gh, s, p)
    assert np.allclose(got[0], rh[0]) and np.allclose(got[1], rh[1]), \
        f"dx, dw for kernel ({kh}, {kw}), stride {s}, padding {p}"
    # the adjoint identity <conv(dx0, w), g> = <dx0, dx> (conv is linear in x, bias 0)
    # is checked with the forward pass written in the ex02_1 grade cell's style
    x0 = rng.standard_normal(xh.shape)
    fwd = np.zeros(gh.shape)
    for i in range(ho):
        for j in range(wo):
            for u in range(kh):
                for v in range(kw):
                    r, q = s * i + u - p, s * j + v - p
                    if 0 <= r < 7 and 0 <= q < 6:
                        fwd[:, i, j, :] += x0[:, r, q, :] @ wh[u, v]
    assert np.isclose(np.sum(fwd * gh), np.sum(x0 * got[0])), "<conv(x0), g> = <x0, dx>"
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 2.3 — global average pooling, forward and backward
# `gap_forward(x)` maps `(N, H, W, C)` to `(N, C)`, the mean over the two
# spatial axes (eq. 7). `gap_backward(g, x_shape)` returns the cotangent of `x`
# for an output cotangent `g` of shape `(N, C)`: every pixel contributed
# `1 / (H W)` of the mean.

# %% solution id=ex02_3 title="Global average pooling" forbids="minimanc.autodiff.nn.global_avg_pool,minimanc.layers.global_avg_pool,minimanc.cam.global_average_pool"  # noqa: E501
def gap_forward(x):
    ### BEGIN SOLUTION
    return x.mean(axis=(1, 2))
    ### END SOLUTION


def gap_backward(g, x_shape):
    ### BEGIN SOLUTION
    n, h, w, c = x_shape
    return np.broadcast_to(g[:, None, None, :] / (h * w), x_shape).copy()
    ### END SOLUTION

# %% grade id=ex02_3_tests points=2
feat = rng.standard_normal((3, 4, 5, 2))
assert gap_forward(feat).shape == (3, 2), "(N, H, W, C) -> (N, C) = (3, 2)"
assert np.allclose(gap_forward(feat), [[feat[n, :, :, c].sum() / 20 for c in range(2)]
                                        for n in range(3)]), "the mean over 4 x 5 = 20 pixels"
gy = rng.standard_normal((3, 2))
dfeat = gap_backward(gy, feat.shape)
assert dfeat.shape == feat.shape, "the cotangent of x has the shape of x"
assert np.allclose(dfeat, np.repeat(np.repeat(gy[:, None, None, :], 4, 1), 5, 2) / 20), \
    "g / 20 at every pixel"
# the adjoint identity <gap(f), gy> = <f, dfeat> for any f
assert np.isclose(np.sum(gap_forward(feat) * gy), np.sum(feat * dfeat)), "<gap(f), g> = <f, dfeat>"
### BEGIN HIDDEN TESTS
one = rng.standard_normal((1, 1, 1, 4))
assert np.allclose(gap_forward(one), one[:, 0, 0]), "a 1x1 image is its own mean"
assert np.allclose(gap_backward(np.ones((2, 3)), (2, 8, 2, 3)), 1 / 16), "1 / (8 * 2) everywhere"
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 2.4 — one Adam step
# For one parameter array, return `(theta, m, v)` after step number `t`
# (counting from 1):
# $m \leftarrow \beta_1 m + (1-\beta_1) g$, $v \leftarrow \beta_2 v + (1-\beta_2) g^2$,
# $\hat m = m / (1-\beta_1^t)$, $\hat v = v / (1-\beta_2^t)$,
# $\theta \leftarrow \theta - \gamma\, \hat m / (\sqrt{\hat v} + \epsilon)$.

# %% solution id=ex02_4 title="Adam step" forbids="minimanc.optim.adam_update"
def adam_step(theta, g, m, v, t, lr=1e-3, b1=0.9, b2=0.999, eps=1e-8):
    ### BEGIN SOLUTION
    m = b1 * m + (1 - b1) * g
    v = b2 * v + (1 - b2) * g * g
    m_hat = m / (1 - b1 ** t)
    v_hat = v / (1 - b2 ** t)
    return theta - lr * m_hat / (np.sqrt(v_hat) + eps), m, v
    ### END SOLUTION

# %% grade id=ex02_4_tests points=2
theta0 = np.array([1.0, -2.0])
grad0 = np.array([0.5, 0.0])
theta1, m1, v1 = adam_step(theta0, grad0, np.zeros(2), np.zeros(2), t=1, lr=0.1)
assert np.allclose(m1, [0.05, 0.0]) and np.allclose(v1, [0.00025, 0.0]), \
    "m = 0.1 g = [0.05, 0], v = 0.001 g^2 = [0.00025, 0]"
assert np.allclose(theta1, [0.9, -2.0]), "the first step moves by lr times sign(g)"


def adam_reference(theta, grads, lr, b1, b2, eps):
    """Adam written out for a scalar with Python floats, the first moments bias-corrected
    by hand: an independent reference."""
    m = v = 0.0
    for t, gt in enumerate(grads, start=1):
        m = b1 * m + (1 - b1) * gt
        v = b2 * v + (1 - b2) * gt ** 2
        theta = theta - lr * (m / (1 - b1 ** t)) / (math.sqrt(v / (1 - b2 ** t)) + eps)
    return theta, m, v


gs = rng.standard_normal((5, 2))
theta, m, v = theta0, np.zeros(2), np.zeros(2)
for t in range(1, 6):
    theta, m, v = adam_step(theta, gs[t - 1], m, v, t, lr=0.05)
for k in range(2):
    ref = adam_reference(theta0[k], gs[:, k], 0.05, 0.9, 0.999, 1e-8)
    assert np.allclose([theta[k], m[k], v[k]], ref), f"coordinate {k}: theta, m, v after 5 steps"
### BEGIN HIDDEN TESTS
gs = rng.standard_normal((7, 3))
theta, m, v = np.ones(3), np.zeros(3), np.zeros(3)
for t in range(1, 8):
    theta, m, v = adam_step(theta, gs[t - 1], m, v, t, lr=0.01, b1=0.5, b2=0.9, eps=1e-3)
for k in range(3):
    ref = adam_reference(1.0, gs[:, k], 0.01, 0.5, 0.9, 1e-3)
    assert np.allclose([theta[k], m[k], v[k]], ref), f"coordinate {k}: theta, m, v after 7 steps"
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 2.5 — He initialisation of a convolution
# Return `{"w": w, "b": b}` for a 3×3 (or any) convolution in HWIO layout:
# `w` of shape `(kh, kw, c_in, c_out)` drawn from $\mathcal N(0, \sigma^2)$ with
# He's $\sigma = \sqrt{2 / n_\text{in}}$, and `b` zeros of shape `(c_out,)`.
# What is $n_\text{in}$ for a convolution? Count the inputs that one output
# element sums over. Draw `w` with **one** call
# `rng.standard_normal((kh, kw, c_in, c_out))` and scale it.
#
# *Hint.* If the depth test of the grade cell finds the signal dying (or
# exploding) after ten layers, your $n_\text{in}$ is $c_\text{in}$ alone (or
# $c_\text{out}$): the window is $k_h k_w c_\text{in}$ numbers.

# %% solution id=ex02_5 title="He initialisation" forbids="minimanc.layers.init_conv"
def he_conv_init(rng, kh, kw, c_in, c_out):
    ### BEGIN SOLUTION
    std = math.sqrt(2.0 / (kh * kw * c_in))
    return {"w": std * rng.standard_normal((kh, kw, c_in, c_out)), "b": np.zeros(c_out)}
    ### END SOLUTION

# %% grade id=ex02_5_tests points=2
p5 = he_conv_init(np.random.default_rng(0), 3, 3, 3, 8)
assert set(p5) == {"w", "b"}, f"keys 'w' and 'b' expected, got {sorted(p5)}"
assert p5["w"].shape == (3, 3, 3, 8) and p5["b"].shape == (8,), "w (3, 3, 3, 8) HWIO, b (8,)"
assert np.all(p5["b"] == 0), "the bias starts at zero"
# sigma = sqrt(2 / (3 * 3 * 3)): one output sums over a 3x3 window of 3 channels
same_draws = math.sqrt(2 / 27) * np.random.default_rng(0).standard_normal((3, 3, 3, 8))
assert np.allclose(p5["w"], same_draws), "w = sqrt(2 / (kh kw c_in)) * standard normal draws"
big = he_conv_init(np.random.default_rng(1), 3, 3, 64, 128)["w"]
assert abs(big.std() / math.sqrt(2 / 576) - 1) < 0.03, \
    f"std sqrt(2/576) = 0.0589 expected, got {big.std():.4f}"
### BEGIN HIDDEN TESTS
rng5 = np.random.default_rng(2)
h5 = rng5.standard_normal((256, 128))
for _ in range(10):  # ten 1x1 convolutions with ReLU: He keeps the scale of the signal
    h5 = np.maximum(h5 @ he_conv_init(rng5, 1, 1, 128, 128)["w"][0, 0], 0)
assert 0.3 < h5.std() < 3, f"after 10 ReLU layers the std should stay O(1), got {h5.std():.3g}"
tall = he_conv_init(np.random.default_rng(3), 5, 1, 40, 7)["w"]
assert tall.shape == (5, 1, 40, 7), "kh=5, kw=1: shape (5, 1, 40, 7)"
assert np.allclose(tall, math.sqrt(2 / 200) * np.random.default_rng(3).standard_normal(
    (5, 1, 40, 7))), "n_in = kh kw c_in = 200 (c_out does not enter)"
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 2.6 — one step of SGD with momentum
# For one parameter array, return `(theta, velocity)` after one step of the
# heavy ball: $v \leftarrow \mu v + g$, $\theta \leftarrow \theta - \gamma v$.
# With `nesterov=True`, look ahead along the new velocity:
# $\theta \leftarrow \theta - \gamma (g + \mu v)$ (with the **new** $v$). With
# $\mu = 0$ both are plain gradient descent.

# %% solution id=ex02_6 title="SGD with momentum" forbids="minimanc.optim.sgd_update"
def momentum_step(theta, g, velocity, lr, mu, nesterov=False):
    ### BEGIN SOLUTION
    velocity = mu * velocity + g
    if nesterov:
        return theta - lr * (g + mu * velocity), velocity
    return theta - lr * velocity, velocity
    ### END SOLUTION

# %% grade id=ex02_6_tests points=2
th, vel = momentum_step(np.array([1.0, -1.0]), np.array([2.0, 0.5]), np.zeros(2), 0.1, 0.9)
assert np.allclose(vel, [2.0, 0.5]), "from rest the velocity is the gradient"
assert np.allclose(th, [0.8, -1.05]), "theta - lr * v = [1 - 0.2, -1 - 0.05]"
th, vel = momentum_step(th, np.array([2.0, 0.5]), vel, 0.1, 0.9)
assert np.allclose(vel, [3.8, 0.95]), "v = 0.9 * [2, 0.5] + [2, 0.5]"
assert np.allclose(th, [0.42, -1.145]), "theta = [0.8 - 0.38, -1.05 - 0.095]"
same, _ = momentum_step(np.ones(3), np.arange(3.0), np.full(3, 7.0), 0.5, 0.0)
assert np.allclose(same, 1 - 0.5 * np.arange(3.0)), "mu = 0: plain gradient descent"
### BEGIN HIDDEN TESTS
# a constant gradient c: v_t = c (1 - mu^t) / (1 - mu), theta_t = -lr c sum_k (1 - mu^k)/(1 - mu)
c6, lr6, mu6 = np.array([1.0, -3.0]), 0.05, 0.8
th6, v6 = np.zeros(2), np.zeros(2)
for t6 in range(1, 21):
    th6, v6 = momentum_step(th6, c6, v6, lr6, mu6)
    assert np.allclose(v6, c6 * (1 - mu6 ** t6) / (1 - mu6)), f"velocity at step {t6}"
want6 = -lr6 * c6 * sum((1 - mu6 ** k) / (1 - mu6) for k in range(1, 21))
assert np.allclose(th6, want6), "theta after 20 steps of a constant gradient"
thn, vn = momentum_step(np.array([1.0]), np.array([2.0]), np.array([1.0]), 0.1, 0.5, True)
assert np.allclose(vn, [2.5]) and np.allclose(thn, [1 - 0.1 * (2 + 0.5 * 2.5)]), \
    "Nesterov: v = 0.5 * 1 + 2 = 2.5, theta = 1 - 0.1 (2 + 0.5 * 2.5) = 0.675"
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 2.7 — the index computation of im2col
# im2col gathers every window of the padded image into one row of a matrix.
# Write the indices first: `im2col_indices(h, w, kh, kw, stride, padding)`
# returns integer arrays `rows`, `cols` of shape `(Ho * Wo, kh * kw)` such that
# output pixel $(i, j)$ (row $i W_o + j$) reads the padded pixel
# `(rows[i * Wo + j, u * kw + v], cols[i * Wo + j, u * kw + v])` = $(s i + u,\ s j + v)$
# at kernel offset $(u, v)$. Then `im2col(x, kh, kw, stride, padding)` pads `x`,
# indexes it with them (`xpad[:, rows, cols, :]` has shape
# `(N, Ho Wo, kh kw, C)`) and reshapes to `(N Ho Wo, kh kw C)`, so that
# `im2col(x, ...) @ w.reshape(kh * kw * C, O)` is the convolution.
#
# *Hint.* `np.arange(ho)` repeated `wo` times gives $i$ for every row,
# `np.tile(np.arange(wo), ho)` gives $j$; broadcast them against the offsets.

# %% solution id=ex02_7 title="im2col indices" forbids="minimanc.autodiff.nn.conv2d,minimanc.layers.conv2d,minimanc.autodiff.nn._im2col,minimanc.autodiff.nn._conv_fwd"  # noqa: E501
def im2col_indices(h, w, kh, kw, stride=1, padding=0):
    ### BEGIN SOLUTION
    ho = (h + 2 * padding - kh) // stride + 1
    wo = (w + 2 * padding - kw) // stride + 1
    i = np.repeat(np.arange(ho), wo)[:, None]
    j = np.tile(np.arange(wo), ho)[:, None]
    u = np.repeat(np.arange(kh), kw)[None, :]
    v = np.tile(np.arange(kw), kh)[None, :]
    return stride * i + u, stride * j + v
    ### END SOLUTION


def im2col(x, kh, kw, stride=1, padding=0):
    ### BEGIN SOLUTION
    n, h, w, c = x.shape
    rows, cols = im2col_indices(h, w, kh, kw, stride, padding)
    xpad = np.pad(x, ((0, 0), (padding, padding), (padding, padding), (0, 0)))
    return xpad[:, rows, cols, :].reshape(n * rows.shape[0], kh * kw * c)
    ### END SOLUTION

# %% grade id=ex02_7_tests points=3
rows, cols = im2col_indices(4, 4, 3, 3)
assert rows.shape == (4, 9) and cols.shape == (4, 9), "2 x 2 outputs, 3 x 3 windows"
assert rows[0].tolist() == [0, 0, 0, 1, 1, 1, 2, 2, 2], "output (0, 0): rows u = 0, 0, 0, 1, ..."
assert cols[1].tolist() == [1, 2, 3, 1, 2, 3, 1, 2, 3], "output (0, 1): cols 1 + v"
assert rows[2].tolist() == [1, 1, 1, 2, 2, 2, 3, 3, 3], "output (1, 0): rows 1 + u"
img7 = np.arange(16.0).reshape(1, 4, 4, 1)
assert im2col(img7, 3, 3).astype(int).tolist() == [  # the matrix printed in the tutorial
    [0, 1, 2, 4, 5, 6, 8, 9, 10], [1, 2, 3, 5, 6, 7, 9, 10, 11],
    [4, 5, 6, 8, 9, 10, 12, 13, 14], [5, 6, 7, 9, 10, 11, 13, 14, 15]], "im2col of arange(16)"
r2, c2 = im2col_indices(5, 6, 3, 3, stride=2, padding=1)
assert r2.shape == (3 * 3, 9), "(5 + 2 - 3) // 2 + 1 = 3 and (6 + 2 - 3) // 2 + 1 = 3 outputs"
assert r2[4, 0] == 2 and c2[4, 0] == 2 and r2[8, 8] == 6 and c2[8, 8] == 6, \
    "output (1, 1) starts at padded pixel (2, 2); output (2, 2) ends at (4 + 2, 4 + 2)"
### BEGIN HIDDEN TESTS
def loop_conv7(x, w, stride, padding):
    """The definition of the convolution, one output element at a time."""
    n, h, wd, c = x.shape
    kh, kw, _, o = w.shape
    ho, wo = (h + 2 * padding - kh) // stride + 1, (wd + 2 * padding - kw) // stride + 1
    y = np.zeros((n, ho, wo, o))
    for i in range(ho):
        for j in range(wo):
            for u in range(kh):
                for v in range(kw):
                    r, q = stride * i + u - padding, stride * j + v - padding
                    if 0 <= r < h and 0 <= q < wd:
                        y[:, i, j, :] += x[:, r, q, :] @ w[u, v]
    return y


for kh, kw, s, p in [(3, 3, 1, 1), (2, 3, 2, 0), (3, 2, 3, 2), (1, 1, 1, 0)]:
    x7 = rng.standard_normal((2, 7, 6, 3))
    w7 = rng.standard_normal((kh, kw, 3, 4))
    col7 = im2col(x7, kh, kw, s, p)
    ho7, wo7 = (7 + 2 * p - kh) // s + 1, (6 + 2 * p - kw) // s + 1
    assert col7.shape == (2 * ho7 * wo7, kh * kw * 3), f"col shape for k=({kh},{kw}) s={s}"
    y7 = (col7 @ w7.reshape(kh * kw * 3, 4)).reshape(2, ho7, wo7, 4)
    assert np.allclose(y7, loop_conv7(x7, w7, s, p)), f"col @ W is the conv, k=({kh},{kw}) s={s}"
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 2.8 — softmax cross-entropy and its gradient
# For logits `z` of shape `(B, K)` and integer labels `y` of shape `(B,)`, return
# `(loss, dz)`: the mean cross-entropy
# $L = -\frac1B \sum_b \log \mathrm{softmax}(z_b)_{y_b}$ and its gradient
# $\partial L / \partial z = (\mathrm{softmax}(z) - \mathrm{onehot}(y)) / B$.
# Compute $\log\mathrm{softmax}$ stably: subtract each row's maximum before
# `np.exp` (logits of 1000 must not overflow).

# %% solution id=ex02_8 title="Softmax cross-entropy gradient" forbids="minimanc.autodiff.nn.softmax,minimanc.autodiff.nn.log_softmax"  # noqa: E501
def xent_and_grad(z, y):
    ### BEGIN SOLUTION
    shifted = z - z.max(axis=1, keepdims=True)
    logp = shifted - np.log(np.exp(shifted).sum(axis=1, keepdims=True))
    b = len(y)
    onehot = np.eye(z.shape[1])[y]
    return -np.sum(logp * onehot) / b, (np.exp(logp) - onehot) / b
    ### END SOLUTION

# %% grade id=ex02_8_tests points=2
loss8, dz8 = xent_and_grad(np.zeros((2, 3)), np.array([0, 2]))
assert np.isclose(loss8, math.log(3)), "uniform over 3 classes: loss log 3"
assert np.allclose(dz8, (np.full((2, 3), 1 / 3) - np.eye(3)[[0, 2]]) / 2), \
    "(softmax - onehot) / B with softmax = 1/3"
loss8, dz8 = xent_and_grad(np.array([[0.0, math.log(3.0)]]), np.array([0]))
assert np.isclose(loss8, math.log(4)) and np.allclose(dz8, [[-0.75, 0.75]]), \
    "softmax [1/4, 3/4]: loss log 4, gradient [1/4 - 1, 3/4]"
big8 = xent_and_grad(np.array([[1000.0, 0.0], [0.0, 1000.0]]), np.array([0, 0]))
assert np.isfinite(big8[0]) and np.isclose(big8[0], 500.0), \
    "logits of 1000: no overflow, loss (0 + 1000) / 2 = 500"
### BEGIN HIDDEN TESTS
z8 = rng.standard_normal((5, 4)) * 3
y8 = np.array([3, 0, 1, 1, 2])
loss8, dz8 = xent_and_grad(z8, y8)


def xent_plain(z):  # the definition, with a row-wise log-sum-exp written out
    return -np.mean([z[b, y8[b]] - math.log(sum(math.exp(v) for v in z[b])) for b in range(5)])


assert np.isclose(loss8, xent_plain(z8)), "the loss is the mean of -log softmax(z_b)[y_b]"
fd8 = np.zeros_like(z8)
for idx in np.ndindex(z8.shape):
    e8 = np.zeros_like(z8)
    e8[idx] = 1e-6
    fd8[idx] = (xent_plain(z8 + e8) - xent_plain(z8 - e8)) / 2e-6
assert np.allclose(dz8, fd8, atol=1e-7), "dz must match central differences of the loss"
assert np.allclose(dz8.sum(axis=1), 0), "each row of (softmax - onehot) sums to zero"
### END HIDDEN TESTS

# %% [markdown]
# ## Putting it together
# With the library's versions (so this runs even with unfinished exercises):
# eq. 7 as a model — two convolutions, global average pooling, a linear layer
# — fitted with Adam to predict the mean colour of random images. The loss
# must fall by two orders of magnitude. (150 Adam steps of a non-convex network:
# the printed losses depend on the CPU's summation order, so this cell is checked
# by its assert, not by its digits.)

# %% tags=["nbval-ignore-output"]
images = rng.random((64, 12, 12, 3))
targets = images.mean(axis=(1, 2))
params = {"c1": layers.init_conv(rng, 3, 3, 3, 8), "c2": layers.init_conv(rng, 3, 3, 8, 8),
          "out": layers.init_dense(rng, 8, 3)}


def loss_fn(params, x, y):
    h = nn.silu(layers.conv2d(params["c1"], x, nn, stride=2, padding=1))
    h = nn.silu(layers.conv2d(params["c2"], h, nn, stride=1, padding=1))
    pred = layers.dense(params["out"], layers.global_avg_pool(h, nn), xp=xp)
    return xp.mean((pred - y) ** 2)


state = optim.adam_init(params)
value_and_grad = eng.value_and_grad(loss_fn)
history = []
for _ in range(150):
    loss, grads = value_and_grad(params, images, targets)
    params, state = optim.adam_update(grads, state, params, lr=1e-2)
    history.append(float(loss))
print(f"loss: first {history[0]:.4f}   last {history[-1]:.6f}")
assert history[-1] < history[0] / 100
