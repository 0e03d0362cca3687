# %% [markdown]
# # Chapter 6 — Exercises: pooling, class activation maps, overlays
#
# Module built in this chapter: `minimanc.cam` (paper eq. 7 and Figures 3–4).
# Replace each `raise NotImplementedError(...)` with your code and run the
# grade cell below it; `minimanc grade exercises/06_cam.ipynb` scores the
# notebook.
#
# Layouts: features are channels-last `(B, H, W, K)`; the linear head's weight
# is `(K, M)` so that `p = gap(f) @ w + b`; CAMs are `(B, M, H, W)`.

# %%
import matplotlib.pyplot as plt
import numpy as np

from minimanc import cam

rng = np.random.default_rng(0)

# %% [markdown]
# ## Exercise 6.1 — global average pooling
# Return the mean of each feature map over its height and width:
# `(B, H, W, K) → (B, K)`. This is the "GlobalAveragePooling" of eq. 7.

# %% solution id=ex06_1 title="Global average pooling" forbids="minimanc.cam.global_average_pool,minimanc.layers.global_avg_pool,minimanc.autodiff.nn.global_avg_pool"  # noqa: E501
def global_avg_pool(features):
    ### BEGIN SOLUTION
    return np.asarray(features, float).mean(axis=(1, 2))
    ### END SOLUTION

# %% grade id=ex06_1_tests points=1
f = np.zeros((1, 2, 2, 3))
f[0, 0, 0] = [4.0, 0.0, 8.0]
assert global_avg_pool(f).shape == (1, 3)
assert np.allclose(global_avg_pool(f), [[1.0, 0.0, 2.0]])
### BEGIN HIDDEN TESTS
fr = rng.normal(size=(3, 5, 7, 4))
assert np.allclose(global_avg_pool(fr), fr.sum(axis=(1, 2)) / 35)
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 6.2 — class activation maps
# For features `(B, H, W, K)` and head weights `w` of shape `(K, M)`, return
# $M_i(x, y) = \sum_k w_{ki} f_k(x, y)$ with shape `(B, M, H, W)` (predicate
# axis before the spatial axes). No bias: the bias is not located anywhere in
# the image.

# %% solution id=ex06_2 title="Class activation maps" forbids="minimanc.cam.class_activation_maps"  # noqa: E501
def class_activation_maps(features, w):
    ### BEGIN SOLUTION
    return np.einsum("bhwk,km->bmhw", np.asarray(features, float), np.asarray(w, float))
    ### END SOLUTION

# %% grade id=ex06_2_tests points=3
f = rng.random((2, 4, 5, 3))
w = rng.normal(size=(3, 2))
b = rng.normal(size=2)
maps = class_activation_maps(f, w)
assert maps.shape == (2, 2, 4, 5), maps.shape
p = f.mean(axis=(1, 2)) @ w + b
assert np.allclose(maps.mean(axis=(2, 3)) + b, p), "mean of the CAM + bias must give p"
assert np.allclose(maps[1, 0], f[1] @ w[:, 0])
### BEGIN HIDDEN TESTS
fr, wr = rng.normal(size=(3, 6, 2, 5)), rng.normal(size=(5, 4))
ref = np.stack([[fr[n] @ wr[:, m] for m in range(4)] for n in range(3)])
assert np.allclose(class_activation_maps(fr, wr), ref)
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 6.3 — the overlay normalisation
# Overlays show the *ranking* of pixels, so each map is min–max normalised to
# $[0, 1]$: $(s - \min s)/(\max s - \min s)$, separately for every map of a
# stack `(..., H, W)`. A constant map has no ranking: return zeros for it
# (not `nan`).

# %% solution id=ex06_3 title="Min-max normalisation of saliency maps" forbids="minimanc.cam.minmax_normalize"  # noqa: E501
def normalise(maps):
    ### BEGIN SOLUTION
    maps = np.asarray(maps, float)
    lo = maps.min(axis=(-2, -1), keepdims=True)
    span = maps.max(axis=(-2, -1), keepdims=True) - lo
    return np.where(span > 0, (maps - lo) / np.where(span > 0, span, 1.0), 0.0)
    ### END SOLUTION

# %% grade id=ex06_3_tests points=2
s = np.array([[1.0, 3.0], [5.0, 2.0]])
assert np.allclose(normalise(s), [[0.0, 0.5], [1.0, 0.25]])
stack = np.stack([s, 10 * s - 4])
assert np.allclose(normalise(stack), normalise(s)[None]), "each map separately"
flat = normalise(np.full((3, 3), 7.0))
assert np.all(np.isfinite(flat)) and np.allclose(flat, 0.0), "constant map -> zeros"
### BEGIN HIDDEN TESTS
sr = rng.normal(size=(2, 3, 6, 5))
lo, hi = sr.min(axis=(2, 3), keepdims=True), sr.max(axis=(2, 3), keepdims=True)
assert np.allclose(normalise(sr), (sr - lo) / (hi - lo))
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
cam.overlay(img, maps[0, 0], ax=axes[1], title="'vehicle' CAM")
plt.show()
