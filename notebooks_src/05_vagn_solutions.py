# %% [markdown]
# # Chapter 5 — Exercises: the vAGN soft automaton
#
# Module built in this chapter: `minimanc.vagn` (paper eqs. 8–9). Replace
# each `raise NotImplementedError(...)` with your code and run the grade cell
# below it; `minimanc grade exercises/05_vagn.ipynb` scores the notebook.
#
# Conventions: `W` has shape `(M, N, N)` (one matrix per predicate),
# `T[i, j] = P(next = i | current = j)` so **columns** sum to one, and one
# step is `q_t = T @ q_{t-1}`.

# %%
import numpy as np

from minimanc import vagn

rng = np.random.default_rng(0)

# %% [markdown]
# ## Exercise 5.1 — the transition matrix (eqs. 8–9)
# Given predicates `p` of shape `(M,)` and weights `W` of shape `(M, N, N)`,
# return $T = \mathrm{colsoftmax}(\mathrm{ReLU}(\sum_i p_i W_i))$, shape `(N, N)`.
# Subtract each column's maximum before `np.exp` so that large weights do not
# overflow.

# %% solution id=ex05_1 title="vAGN transition matrix" forbids="minimanc.vagn.transition_matrix"
def transition_matrix(p, W):
    ### BEGIN SOLUTION
    A = np.tensordot(np.asarray(p, float), np.asarray(W, float), axes=1)  # eq. 8
    R = np.maximum(A, 0.0)
    E = np.exp(R - R.max(axis=0, keepdims=True))
    return E / E.sum(axis=0, keepdims=True)  # eq. 9, softmax along each column
    ### END SOLUTION

# %% grade id=ex05_1_tests points=3
W = np.zeros((2, 2, 2))
W[0] = [[2.0, 0.0], [0.0, -1.0]]
T = transition_matrix(np.array([1.0, 0.0]), W)
assert T.shape == (2, 2)
assert np.allclose(T.sum(axis=0), 1.0), "every column must sum to one"
assert np.isclose(T[0, 0], np.exp(2) / (np.exp(2) + 1)), "softmax along the column"
assert np.allclose(T[:, 1], 0.5), "ReLU(-1) = 0 and e^0 = 1: a uniform column"
### BEGIN HIDDEN TESTS
for _ in range(5):
    Wr = rng.normal(size=(4, 3, 3)) * 3
    pr = rng.random(4)
    Er = np.exp(np.maximum(np.tensordot(pr, Wr, axes=1), 0.0))
    assert np.allclose(transition_matrix(pr, Wr), Er / Er.sum(axis=0))
big = transition_matrix(np.ones(1), np.full((1, 3, 3), 1000.0) + np.eye(3))
assert np.all(np.isfinite(big)) and np.allclose(big.sum(axis=0), 1.0)
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 5.2 — one step, for a batch
# Apply eq. 9 to a batch: `q` has shape `(B, N)`, `p` has shape `(B, M)`;
# return the new distributions, shape `(B, N)`. `vagn.transition_matrix`
# (the library's) accepts a batch of predicates and returns `(B, N, N)`;
# `np.einsum` is handy for the batched matrix–vector product.

# %% solution id=ex05_2 title="One vAGN step" forbids="minimanc.vagn.step"
def vagn_step(q, p, W):
    ### BEGIN SOLUTION
    T = vagn.transition_matrix(p, W)  # (B, N, N)
    return np.einsum("bij,bj->bi", T, q)
    ### END SOLUTION

# %% grade id=ex05_2_tests points=2
Wb = rng.normal(size=(3, 4, 4))
pb = rng.random((5, 3))
qb = vagn.random_state(rng, 4, size=5)
out = vagn_step(qb, pb, Wb)
assert out.shape == (5, 4)
assert np.allclose(out.sum(axis=1), 1.0), "q must stay a distribution"
assert np.allclose(out[2], vagn.transition_matrix(pb[2], Wb) @ qb[2])
### BEGIN HIDDEN TESTS
assert np.allclose(out, [vagn.transition_matrix(pb[i], Wb) @ qb[i] for i in range(5)])
assert np.allclose(vagn_step(np.eye(4), np.zeros((4, 3)), Wb), 0.25)
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 5.3 — the stationary distribution
# For a column-stochastic `T` with positive entries, return the unique
# distribution $\pi$ with $T\pi = \pi$, entries summing to one. Hint: $\pi$ is
# the eigenvector of eigenvalue 1 (`np.linalg.eig`, take the real part and
# normalise), or the limit of $T^k q$.

# %% solution id=ex05_3 title="Stationary distribution" forbids="minimanc.vagn.stationary_distribution"  # noqa: E501
def stationary(T):
    ### BEGIN SOLUTION
    vals, vecs = np.linalg.eig(np.asarray(T, float))
    v = np.real(vecs[:, np.argmin(np.abs(vals - 1.0))])
    return v / v.sum()
    ### END SOLUTION

# %% grade id=ex05_3_tests points=2
a, b = 0.3, 0.1
pi = stationary(np.array([[1 - a, b], [a, 1 - b]]))
assert np.allclose(pi, [0.25, 0.75]), pi
T3 = vagn.transition_matrix(rng.random(3), rng.normal(size=(3, 3, 3)))
pi3 = stationary(T3)
assert np.isclose(pi3.sum(), 1.0) and np.allclose(T3 @ pi3, pi3)
### BEGIN HIDDEN TESTS
T5 = vagn.transition_matrix(rng.random(2), rng.normal(size=(2, 5, 5)) * 2)
pi5 = stationary(T5)
assert np.allclose(T5 @ pi5, pi5) and np.isclose(pi5.sum(), 1.0)
assert np.all(pi5 > 0)
assert np.allclose(stationary(np.array([[0.5, 0.25, 0.0], [0.5, 0.5, 0.5], [0.0, 0.25, 0.5]])),
                   [0.25, 0.5, 0.25])
### END HIDDEN TESTS

# %% [markdown]
# ## Putting it together
# From here on the library's versions are used, so this cell runs even with
# unfinished exercises. Under constant predicates the automaton forgets where
# it started: two very different start distributions end at the same $\pi$.

# %%
W = vagn.init_vagn(rng, 2, 3, scale=1.5)
p = np.array([0.7, 0.2])
T = vagn.transition_matrix(p, W)
pi = vagn.stationary_distribution(T)
ps = np.tile(p, (40, 1))
for q0 in (np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0])):
    qs = vagn.rollout(q0, ps, W)
    print("start", q0, "-> after 40 steps", np.round(qs[-1], 4))
    assert np.allclose(qs[-1], pi, atol=1e-6)
print("pi =", np.round(pi, 4))
