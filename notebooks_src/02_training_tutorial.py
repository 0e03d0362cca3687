# %% [markdown]
# # Chapter 2 — Training: layers, convolutions and Adam
#
# Modules built in this chapter: `minimanc.layers` (initialisers and functional
# layers), `minimanc.optim` (SGD and Adam on pytrees) and the neural-net
# primitives of `minimanc.autodiff.nn` (`relu`, `silu`, `softmax`, `conv2d`,
# `global_avg_pool`).
#
# The visual predicate extractor of MANC (paper eq. 7) is a small CNN:
#
# $$f^v = \texttt{ConvEncoder}(\mathcal X), \qquad
#   p^v = \texttt{Linear}\big(\texttt{GlobalAveragePooling}(f^v)\big),$$
#
# trained, like everything else in the paper, by gradient descent on a
# behaviour-cloning loss (Algorithm 1). In chapter 1 we built `grad`; here we
# build what it needs to train such a network: layers as pure functions of
# `(params, inputs)`, a convolution with a fast forward *and* backward pass,
# and the Adam optimiser. Then we train a tiny CNN on a toy bird's-eye-view
# task and run the very same code on JAX.
#
# Plan: (1) parameters and layers, (2) initialisation, (3) the convolution by
# loops, (4) im2col, (5) the backward pass of a convolution, (6) global average
# pooling, (7) optimisers: SGD, momentum, Adam, (8) a toy BEV task,
# (9) training, (10) the same model on JAX.
#
# **Objectives.** After this chapter you can
# - write a convolution's forward and backward passes (by loops and by im2col)
# - initialise layers so that the signal survives depth (He, Glorot)
# - implement SGD, momentum and Adam on pytrees and train a small CNN
#
# **Prerequisites.** Chapter 1 (VJPs, `grad`); matrix products; what a loss and a gradient
# step are.
#
# **Time.** About 60 minutes for the tutorial and 150 for the exercises.

# %%
import time

import matplotlib.pyplot as plt
import numpy as np
from numpy.lib.stride_tricks import as_strided

from minimanc import engine, layers, optim
from minimanc.autodiff import check_grads, nn

rng = np.random.default_rng(0)
eng = engine("numpy")
xp = eng.xp

# %% [markdown]
# ## 1. Parameters are pytrees, layers are pure functions
# A layer is two functions: an **initialiser** that draws parameters from a
# `numpy.random.Generator`, and a **forward function** `layer(params, x, xp)`
# with no hidden state. Parameters are plain dicts of arrays, so a whole model
# is a nested dict — a *pytree* — and `grad` returns a gradient with the same
# structure.

# %%
p = layers.init_dense(rng, 4, 3)
print({k: v.shape for k, v in p.items()})
x = rng.standard_normal((5, 4))
y = layers.dense(p, x, xp=xp)               # x @ w + b
assert np.allclose(y, x @ p["w"] + p["b"])

g = eng.grad(lambda p: xp.sum(layers.dense(p, x, xp=xp) ** 2))(p)
print({k: v.shape for k, v in g.items()})   # same structure as p

# %% [markdown]
# ## 2. Initialisation: keep the signal alive
# With random weights $w \sim \mathcal N(0, \sigma^2)$, each layer multiplies the
# variance of its input by about $n_\text{in}\sigma^2$ (and ReLU halves it). Too
# small and the signal dies after a few layers, too large and it explodes.
# **He** initialisation, $\sigma^2 = 2/n_\text{in}$, keeps the variance of ReLU
# activations constant; **Glorot**, $w \sim U(-a, a)$ with
# $a = \sqrt{6/(n_\text{in}+n_\text{out})}$, balances forward and backward
# variances for layers without ReLU. `init_conv` uses He with
# $n_\text{in} = k_h k_w c_\text{in}$, `init_dense` and `init_lstm` use Glorot.

# %%
h_he = h_small = rng.standard_normal((256, 128))
for depth in range(1, 11):
    w_he = layers.init_conv(rng, 1, 1, 128, 128)["w"][0, 0]    # He: std sqrt(2/128)
    h_he = np.maximum(h_he @ w_he, 0)
    h_small = np.maximum(h_small @ (0.01 * rng.standard_normal((128, 128))), 0)
    if depth in (1, 5, 10):
        print(f"depth {depth:2d}: std He {h_he.std():.3f}   std N(0, 0.01^2) {h_small.std():.2e}")
assert 0.3 < h_he.std() < 3 and h_small.std() < 1e-8

# %% [markdown]
# ## 3. The convolution, by loops
# Images are **NHWC** (batch, height, width, channels) and kernels **HWIO**
# (kernel height, kernel width, input channels, output channels). With stride
# $s$ and $p$ pixels of zero padding on each side,
#
# $$y[n, i, j, o] = b[o] + \sum_{u, v, c} x_\text{pad}[n,\, s i + u,\, s j + v,\, c]\,
#   w[u, v, c, o], \qquad H_\text{out} = \left\lfloor \frac{H + 2p - k_h}{s} \right\rfloor + 1 .$$
#
# (Deep learning calls this cross-correlation a convolution: the kernel is
# not flipped.) Written with loops, it is short and obviously right — and slow.

# %%
def conv2d_loops(x, w, b, stride=1, padding=0):
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


x = rng.standard_normal((2, 7, 9, 3))
w = rng.standard_normal((3, 3, 3, 4))
b = rng.standard_normal(4)
y_loops = conv2d_loops(x, w, b, stride=2, padding=1)
y_lib = nn.conv2d(x, w, b, stride=2, padding=1)
print("output shape", y_lib.shape)
assert y_lib.shape == (2, 4, 5, 4) and np.allclose(y_loops, y_lib)

# %% [markdown]
# ## 4. im2col: a convolution is one matrix product
# Gather every window into one row of a matrix `col` of shape
# $(N H_\text{out} W_\text{out},\ k_h k_w C)$; flatten the kernel into
# $W$ of shape $(k_h k_w C,\ O)$; then $y = \mathrm{col}\,W + b$, one GEMM
# that BLAS runs at full speed. In NHWC the result *is* the next activation
# (a reshape, no transpose).
#
# NumPy can build the windows without copying anything: `as_strided` makes a
# 6-D **view** `(N, Hout, Wout, kh, kw, C)` of the padded image, whose strides
# step by `stride` pixels along the output axes and by one pixel along the
# kernel axes. One copy turns it into `col`.

# %%
img = np.arange(16.0).reshape(1, 4, 4, 1)         # one 4x4 single-channel image
s0, s1, s2, s3 = img.strides
windows = as_strided(img, shape=(1, 2, 2, 3, 3, 1), strides=(s0, s1, s2, s1, s2, s3))
col = windows.reshape(4, 9)                        # 2x2 outputs, 3x3 windows
print(col.astype(int))
ker = rng.standard_normal((3, 3, 1, 1))
assert np.allclose((col @ ker.reshape(9, 1)).reshape(1, 2, 2, 1), nn.conv2d(img, ker))

# %% [markdown]
# The library's `nn.conv2d` does exactly this, with a few extra tricks that
# matter on a CPU: the padded image and the column matrix live in buffers that
# are reused from step to step, the bias is folded into the GEMM as a column of
# ones, and float32 stays float32. The loop version pays a Python-level
# iteration per output pixel:

# %%
xb = rng.standard_normal((16, 32, 32, 8)).astype(np.float32)
wb = rng.standard_normal((3, 3, 8, 16)).astype(np.float32)
bb = np.zeros(16, np.float32)
for name, f in (("loops", conv2d_loops), ("im2col", nn.conv2d)):
    t0 = time.perf_counter()
    for _ in range(3):
        f(xb, wb, bb, stride=1, padding=1)
    print(f"{name:7s} {1e3 * (time.perf_counter() - t0) / 3:7.1f} ms per call")

# %% [markdown]
# ## 5. The backward pass of a convolution
# Since $y = \mathrm{col}\, W$, the vector-Jacobian products of chapter 1 give,
# for an output cotangent $\bar y$ (reshaped to rows of `col`):
#
# $$\bar W = \mathrm{col}^\top \bar y, \qquad \bar b = \textstyle\sum_\text{rows} \bar y,
# \qquad \overline{\mathrm{col}} = \bar y\, W^\top .$$
#
# `col` copied each input pixel into every window that contains it, and the
# VJP of a copy is a **sum**: $\bar x$ is obtained by adding each row of
# $\overline{\mathrm{col}}$ back onto the window it came from (*col2im*). The
# forward pass keeps `col` as a residual (`defvjp_fwd`, a JAX `custom_vjp`), so
# the backward pass is two GEMMs and one col2im. With a 3×3 kernel and stride 2
# the four kernel offsets $\{0, 1\}^2$ tile the input exactly (one assignment)
# and the other five are three strided additions.
#
# Here is col2im by loops over the kernel offsets, checked against the library:

# %%
def conv2d_backward_loops(x, w, g, stride, padding):
    """(dx, dw, db) of y = conv2d(x, w, b) for the output cotangent g."""
    xpad = np.pad(x, ((0, 0), (padding, padding), (padding, padding), (0, 0)))
    dxpad, dw = np.zeros_like(xpad), np.zeros_like(w)
    ho, wo = g.shape[1:3]
    for u in range(w.shape[0]):
        for v in range(w.shape[1]):
            rows = slice(u, u + stride * (ho - 1) + 1, stride)
            cols = slice(v, v + stride * (wo - 1) + 1, stride)
            dw[u, v] = np.einsum("nhwc,nhwo->co", xpad[:, rows, cols, :], g)
            dxpad[:, rows, cols, :] += g @ w[u, v].T        # col2im: add back
    dx = dxpad[:, padding:padding + x.shape[1], padding:padding + x.shape[2], :]
    return dx, dw, g.sum(axis=(0, 1, 2))


g_out = rng.standard_normal(y_lib.shape)
by_loops = conv2d_backward_loops(x, w, g_out, stride=2, padding=1)
by_lib = eng.grad(lambda x, w, b: xp.sum(nn.conv2d(x, w, b, 2, 1) * g_out),
                  argnums=(0, 1, 2))(x, w, b)
for name, a, r in zip(("dx", "dw", "db"), by_lib, by_loops):
    agree = np.abs(a - r).max() < 1e-12
    print(f"{name} {a.shape}: library and loops agree to 1e-12: {agree}")
    assert agree

# %% [markdown]
# And the independent oracle of chapter 1, central differences, on every
# element of `x`, `w` and `b`:

# %%
report = check_grads(lambda x, w, b: xp.sum(nn.conv2d(x, w, b, 2, 1) * g_out), x, w, b,
                     verbose=False)
print(f"{report.n_checked} elements checked, max abs error below 1e-6: "
      f"{report.max_abs_err < 1e-6}")
assert report.passed

# %% [markdown]
# ## 6. Global average pooling
# GAP averages each channel over the image: $(N, H, W, C) \to (N, C)$. After
# it, a channel only says *how much* of its pattern the image contains, not
# *where* — that is why MANC's predicates are "is there a pedestrian, an
# intersection …" (eq. 7), and why chapter 6 can map a predicate back onto the
# image (CAM). Its VJP spreads the cotangent evenly: $\bar x = \bar y / (HW)$ at
# every pixel.

# %%
feat = rng.standard_normal((2, 4, 4, 3))
pooled = nn.global_avg_pool(feat)
assert np.allclose(pooled, feat.mean(axis=(1, 2)))
g_pool = eng.grad(lambda f: xp.sum(nn.global_avg_pool(f)[:, 0]))(feat)
print(f"cotangent on channel 0: {g_pool[0, 0, 0, 0]:.4f} = 1/16, "
      f"on channel 1: {g_pool[0, 0, 0, 1]:.1f}")

# %% [markdown]
# ## 7. Optimisers: SGD, momentum, Adam
# An optimiser is a pair of pure functions on pytrees, as in optax:
# `state = init(params)` and `params, state = update(grads, state, params)`.
#
# * **SGD**: $\theta \leftarrow \theta - \gamma g$ (the learning rate $\gamma$ of
#   Algorithm 1).
# * **Momentum**: $v \leftarrow \mu v + g$, $\theta \leftarrow \theta - \gamma v$ —
#   a heavy ball that accumulates speed along consistent directions.
# * **Adam** (Kingma & Ba, 2015): running means of $g$ and $g^2$,
#   $m \leftarrow \beta_1 m + (1-\beta_1) g$, $v \leftarrow \beta_2 v + (1-\beta_2) g^2$,
#   bias-corrected $\hat m = m/(1-\beta_1^t)$, $\hat v = v/(1-\beta_2^t)$, and
#   $\theta \leftarrow \theta - \gamma\, \hat m / (\sqrt{\hat v} + \epsilon)$. Each
#   coordinate gets its own step size, so badly scaled parameters (a conv
#   kernel next to a DMP gain) train together.
#
# On an elongated valley $f(\theta) = \tfrac12(100\,\theta_0^2 + \theta_1^2)$, plain
# SGD must keep $\gamma < 2/100$ for the steep direction and then crawls along
# the flat one:

# %%
scales = np.array([100.0, 1.0])


def valley_grad(theta):
    return {"theta": scales * theta["theta"]}


runs = {"SGD": (optim.sgd_init, optim.sgd_update, {"lr": 0.019, "momentum": 0.0}),
        "momentum": (optim.sgd_init, optim.sgd_update, {"lr": 0.01, "momentum": 0.9}),
        "Adam": (optim.adam_init, optim.adam_update, {"lr": 0.1})}
paths = {}
for name, (init, update, kw) in runs.items():
    theta = {"theta": np.array([1.0, 1.0])}
    state = init(theta)
    path = [theta["theta"]]
    for _ in range(100):
        theta, state = update(valley_grad(theta), state, theta, **kw)
        path.append(theta["theta"])
    paths[name] = np.array(path)
    print(f"{name:8s} after 100 steps: |theta| = {np.linalg.norm(path[-1]):.4f}")
assert np.linalg.norm(paths["Adam"][-1]) < 0.1 < np.linalg.norm(paths["SGD"][-1])

fig, ax = plt.subplots(figsize=(6, 4))
t0_, t1_ = np.meshgrid(np.linspace(-1.2, 1.2, 100), np.linspace(-0.3, 1.2, 100))
ax.contour(t0_, t1_, 100 * t0_ ** 2 + t1_ ** 2, levels=20, colors="0.8")
for name, path in paths.items():
    ax.plot(path[:, 0], path[:, 1], ".-", ms=3, label=name)
ax.set_xlabel("θ0 (steep)")
ax.set_ylabel("θ1 (flat)")
ax.legend()
plt.show()

# %% [markdown]
# ## 8. A toy bird's-eye-view task: is there a car ahead in my lane?
# Chapter 7 builds a nuScenes-style world; here we draw much simpler 32×32
# rasters, ego-centric and heading up, in the devkit's colours: a three-lane
# road (white) with grey lane centre lines, the ego (red), the stretch of the
# ego's own lane ahead (cyan, like the route) and other cars (yellow). The
# ego's lane changes from scene to scene. The label is 1 when a car is ahead
# of us in our lane. Distractors: cars in the neighbouring lanes and cars
# behind us in our lane, which do not count.

# %%
S = 32
ROAD, LANE_LINE, ROUTE = (1.0, 1.0, 1.0), (0.47, 0.53, 0.6), (0.0, 1.0, 1.0)
EGO, CAR = (1.0, 0.0, 0.0), (1.0, 1.0, 0.0)
EGO_ROWS = (20, 26)                               # the ego's box, rows 20..25


def paint(img, r0, r1, c0, c1, colour):
    img[max(r0, 0):max(min(r1, S), 0), max(c0, 0):max(min(c1, S), 0)] = colour


def make_scene(rng):
    img = np.zeros((S, S, 3))
    lane = int(rng.integers(0, 3))                # ego's lane: 0 left, 1 middle, 2 right
    left = S // 2 - 4 - 8 * lane                  # the road's left edge (ego at column 16)
    paint(img, 0, S, left, left + 24, ROAD)
    for k in range(3):
        if k != lane:
            paint(img, 0, S, left + 8 * k + 4, left + 8 * k + 5, LANE_LINE)
    paint(img, 0, EGO_ROWS[0], S // 2 - 4, S // 2 + 4, ROUTE)
    paint(img, *EGO_ROWS, S // 2 - 2, S // 2 + 2, EGO)
    label = int(rng.random() < 0.5)
    cars = []
    for _ in range(int(rng.integers(0, 4))):      # traffic in the other lanes
        k = int(rng.choice([j for j in range(3) if j != lane]))
        cars.append((int(rng.integers(-3, S - 2)), left + 8 * k + 2))
    if rng.random() < 0.3:                        # a car behind us, in our lane
        cars.append((int(rng.integers(EGO_ROWS[1] + 1, S - 1)), S // 2 - 2))
    if label:                                     # the car that matters
        cars.append((int(rng.integers(-3, EGO_ROWS[0] - 7)), S // 2 - 2))
    for r, c in cars:
        paint(img, r, r + 6, c, c + 4, CAR)
    return img, label


def make_dataset(rng, n):
    images, labels = zip(*(make_scene(rng) for _ in range(n)))
    return np.stack(images), np.array(labels)


x_train, y_train = make_dataset(rng, 768)
x_test, y_test = make_dataset(rng, 256)
print(f"train {x_train.shape}, positives {y_train.mean():.3f}; test positives {y_test.mean():.3f}")

fig, axes = plt.subplots(1, 6, figsize=(12, 2.3))
for ax, im, lab in zip(axes, x_train, y_train):
    ax.imshow(im)
    ax.set_title(f"car ahead: {lab}")
    ax.axis("off")
plt.show()

# %% [markdown]
# ## 9. Training a tiny CNN
# The model is eq. 7 with a two-way classifier on top: three 3×3 convolutions
# (8, 16, 16 filters; strides 2, 2, 1; padding 1) with ReLU, global average
# pooling and a linear layer to two logits. The loss is the cross-entropy
# $-\frac1B\sum_b \log \mathrm{softmax}(z_b)_{y_b}$, computed with `log_softmax`
# for numerical stability. **The model is written once**, against `eng`; in
# section 10 we hand it the JAX engine.
#
# Its gradient with respect to the logits is remarkably simple,
# $\partial L/\partial z = (\mathrm{softmax}(z) - \mathrm{onehot}(y))/B$: each
# row pushes the true class up and the others down in proportion to their
# probability, and sums to zero. Checked on three samples:

# %%
z_demo = np.array([[2.0, -1.0], [0.0, 0.0], [-3.0, 1.0]])
onehot_demo = np.eye(2)[[0, 1, 1]]
dz = eng.grad(lambda z: -xp.mean(xp.sum(nn.log_softmax(z, axis=-1) * onehot_demo, axis=-1)))(
    z_demo)
assert np.allclose(dz, (nn.softmax(z_demo, axis=-1) - onehot_demo) / 3)
print(np.round(dz, 4))

# %%
def init_cnn(rng, dtype=np.float64):
    return {"c1": layers.init_conv(rng, 3, 3, 3, 8, dtype=dtype),
            "c2": layers.init_conv(rng, 3, 3, 8, 16, dtype=dtype),
            "c3": layers.init_conv(rng, 3, 3, 16, 16, dtype=dtype),
            "out": layers.init_dense(rng, 16, 2, dtype=dtype)}


def logits_fn(params, images, eng):
    h = eng.nn.relu(layers.conv(params["c1"], images, eng.nn, stride=2, padding=1))
    h = eng.nn.relu(layers.conv(params["c2"], h, eng.nn, stride=2, padding=1))
    h = eng.nn.relu(layers.conv(params["c3"], h, eng.nn, stride=1, padding=1))
    return layers.dense(params["out"], eng.nn.global_avg_pool(h), xp=eng.xp)


def loss_fn(params, images, onehot, eng):
    logp = eng.nn.log_softmax(logits_fn(params, images, eng), axis=-1)
    return -eng.xp.mean(eng.xp.sum(logp * onehot, axis=-1))


def accuracy(params, images, labels):
    return float(np.mean(np.argmax(logits_fn(params, images, eng), axis=-1) == labels))


params = init_cnn(np.random.default_rng(1))
n_params = sum(v.size for layer in params.values() for v in layer.values())
acc0 = accuracy(params, x_test, y_test)
print(f"{n_params} parameters; test accuracy before training {acc0:.3f}")

# %% tags=["nbval-ignore-output"]
# 144 Adam steps of a non-convex network: float64, but BLAS sums in a CPU-dependent
# order and training compounds it, so this cell is checked by its asserts, not its digits
value_and_grad = eng.value_and_grad(loss_fn)
opt_state = optim.adam_init(params)
order_rng = np.random.default_rng(2)
losses, test_acc = [], []
for epoch in range(6):
    order = order_rng.permutation(len(x_train))
    for start in range(0, len(x_train), 32):
        idx = order[start:start + 32]
        loss, grads = value_and_grad(params, x_train[idx], np.eye(2)[y_train[idx]], eng)
        params, opt_state = optim.adam_update(grads, opt_state, params, lr=1e-2)
        losses.append(float(loss))
    test_acc.append(accuracy(params, x_test, y_test))
    print(f"epoch {epoch}: mean loss {np.mean(losses[-24:]):.3f}   "
          f"test accuracy {test_acc[-1]:.3f}")
assert test_acc[-1] >= 0.95, test_acc
assert len(losses) == 6 * 24 and np.mean(losses[-24:]) < 0.1

# %%
fig, (ax0, ax1) = plt.subplots(1, 2, figsize=(10, 3.2))
ax0.plot(losses)
ax0.set_yscale("log")
ax0.set_xlabel("Adam step")
ax0.set_ylabel("cross-entropy (minibatch)")
ax1.plot(range(1, len(test_acc) + 1), test_acc, "o-")
ax1.set_xlabel("epoch")
ax1.set_ylabel("test accuracy")
plt.show()

# %% [markdown]
# Where does the network look? Channel $k$ of the last feature map, weighted
# by the linear layer's weight for class "car ahead", and summed over $k$ is
# the class activation map of chapter 6 (eq. 7 without the pooling). It lights
# up on the car in our lane and stays dark on the distractors.

# %% tags=["nbval-ignore-output"]
def features(params, images):
    h = nn.relu(layers.conv(params["c1"], images, nn, stride=2, padding=1))
    h = nn.relu(layers.conv(params["c2"], h, nn, stride=2, padding=1))
    return nn.relu(layers.conv(params["c3"], h, nn, stride=1, padding=1))


show = [i for i in range(40) if y_test[i] == 1][:3] + [i for i in range(40) if y_test[i] == 0][:3]
cam = features(params, x_test[show]) @ (params["out"]["w"][:, 1] - params["out"]["w"][:, 0])
fig, axes = plt.subplots(1, 6, figsize=(12, 2.3))
for ax, i, m in zip(axes, show, cam):
    ax.imshow(x_test[i])
    ax.imshow(np.kron(m, np.ones((4, 4))), cmap="magma", alpha=0.55, vmin=cam.min(),
              vmax=cam.max())
    ax.set_title(f"label {y_test[i]}")
    ax.axis("off")
plt.show()
pos_peak = cam[:3].max(axis=(1, 2)).min()
neg_peak = cam[3:].max(axis=(1, 2)).max()
print(f"smallest CAM peak with a car ahead {pos_peak:.2f} > largest without {neg_peak:.2f}")
assert pos_peak > neg_peak

# %% [markdown]
# ## 10. The same model on JAX
# `engine("jax")` has the same attributes: `xp` is `jax.numpy`, `nn.conv2d` is
# XLA's convolution, `grad` is `jax.grad`, and `jit` compiles. Nothing in
# `loss_fn` changes. In float64 the two engines agree to rounding error, for
# the loss, for every gradient leaf, and after an Adam step.

# %%
jeng = engine("jax")
params64 = init_cnn(np.random.default_rng(3))
batch = (x_train[:32], np.eye(2)[y_train[:32]])
loss_np, grads_np = eng.value_and_grad(loss_fn)(params64, *batch, eng)
jax_step = jeng.jit(lambda p, s, x, y: (jeng.value_and_grad(loss_fn)(p, x, y, jeng), s))
(loss_jx, grads_jx), _ = jax_step(params64, None, *batch)
print(f"loss numpy {float(loss_np):.6f}   jax {float(loss_jx):.6f}")
assert abs(float(loss_np) - float(loss_jx)) < 1e-5

worst = max(float(np.max(np.abs(grads_np[k][n] - np.asarray(grads_jx[k][n]))))
            for k in grads_np for n in grads_np[k])
print(f"largest gradient difference over all leaves below 1e-12: {worst < 1e-12}")
assert worst < 1e-6

new_np, _ = optim.adam_update(grads_np, optim.adam_init(params64), params64, lr=1e-2)
new_jx, _ = optim.adam_update(grads_jx, optim.adam_init(params64), params64, lr=1e-2)
loss_after = (float(loss_fn(new_np, *batch, eng)), float(loss_fn(new_jx, *batch, jeng)))
print(f"loss after one Adam step: numpy {loss_after[0]:.6f}   jax {loss_after[1]:.6f}")
assert abs(loss_after[0] - loss_after[1]) < 1e-5

# %% [markdown]
# **Speed.** `benchmarks/bench_engine.py` times one training step (forward,
# backward, Adam) of a 3-convolution network on 32 images of 64×64 on both
# engines, interleaved. On a quiet two-core machine the NumPy engine, thanks to
# the im2col convolution and its reused buffers, runs within a small factor of
# JAX-jit in float32 and about as fast in float64 — XLA's advantage is fusion
# and no Python overhead, not magic. For the full experiments of chapter 9 use
# `engine("jax")` with float32.
#
# **What we did not build.** Batch normalisation, dropout, dilated or grouped
# convolutions, second derivatives (use JAX), learning-rate schedules and
# weight decay (a line each on top of `optim`).

# %% [markdown]
# ## Paper vs. this course
# Chapter 2 is infrastructure for eq. 7 (section IV-A of `manc.tex`,
# $p^v = \texttt{Linear}(\texttt{GlobalAveragePooling}(\texttt{ConvEncoder}(\mathcal X)))$).
# Where this course departs from the paper, and where the paper is silent or slips:
#
# * **What the predicate extractor is.** Eq. 7 is exactly conv layers → GAP →
#   one linear map, with *no* nonlinearity after the linear map, so $p^v$ is
#   unbounded. The text never gives the number of layers, filters, kernel
#   sizes or strides: it refers to a table ("F denotes number of filters, K
#   kernel size, S stride") that is not in the paper. Our backbone
#   (`minimanc.models`, chapter 8) is three 3×3 convolutions with stride 2; MANC
#   passes $p^v$ through a sigmoid after eq. 7 (`predicate_activation`), because
#   with unbounded predicates the column softmax of eq. 9 saturated in training.
# * **A framework vs. our engine.** The authors trained in a deep-learning
#   framework (their model code was never released); we train with the
#   engine of chapter 1 or with JAX, the same model code on both (section 10).
# * **NHWC images, HWIO kernels.** JAX/TensorFlow's layout, where an im2col
#   GEMM's output *is* the next activation (section 4). PyTorch uses NCHW, and
#   the authors' environment renders channels-first 3×250×250 rasters; we use
#   64×64×3 in chapter 7 for CPU training.
# * **SiLU, not ReLU, in MANC.** The paper names no activation; the authors'
#   run name suggests SiLU, which `minimanc.models` uses. This chapter's toy CNN
#   uses ReLU, for which He initialisation's $\sigma^2 = 2/n_\text{in}$ is
#   derived exactly; with SiLU it is a good approximation, not an identity.
# * **Adam, not Algorithm 1's plain step.** Algorithm 1 writes plain gradient
#   descent $\theta \leftarrow \theta - \gamma\frac1m\nabla L$ (and, with $L$
#   already a mean, divides by $m$ twice — chapter 1). Its `Initialize(N)` is
#   unspecified; we use He for convolutions and Glorot for dense layers, and
#   train with Adam (section 7), because a conv kernel and the DMP-gain layer
#   next to it need very different step sizes.
# * **Cross-entropy here, MSE there.** The toy task of this chapter is a
#   classification; the paper's loss is the MSE between predicted and human
#   controls (Algorithm 1), which chapters 8–9 use.
