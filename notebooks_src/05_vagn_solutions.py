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
import itertools

import matplotlib.pyplot as plt
import numpy as np

from minimanc import engine, optim, vagn
from minimanc.viz.automaton import plot_automaton_attempts, plot_q_heatmap

rng = np.random.default_rng(0)

# %% [markdown]
# ## Exercise 5.1 — the transition matrix (eqs. 8–9)
# Given predicates `p` of shape `(M,)` and weights `W` of shape `(M, N, N)`,
# return $T = \mathrm{colsoftmax}(\mathrm{ReLU}(\sum_i p_i W_i))$, shape `(N, N)`.
# Subtract each column's maximum before `np.exp` so that large weights do not
# overflow. `vagn.transition_matrix` is switched off while this exercise is
# graded: write your own (5.2 and later may call the library's).

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
assert T.shape == (2, 2), f"expected T of shape (N, N) = (2, 2); got {T.shape}"
assert np.allclose(T.sum(axis=0), 1.0), (
    f"p = (1, 0): expected every column to sum to one; got column sums {T.sum(0)}")
assert np.isclose(T[0, 0], np.exp(2) / (np.exp(2) + 1)), (
    f"p = (1, 0), W_0 = [[2, 0], [0, -1]]: expected T[0, 0] = e^2 / (e^2 + e^0) = 0.8808 "
    f"(softmax along the column); got {T[0, 0]:.4f}")
assert np.allclose(T[:, 1], 0.5), (
    f"p = (1, 0): ReLU(-1) = 0 and e^0 = 1, so expected column 1 = [0.5, 0.5]; got {T[:, 1]}")
### BEGIN HIDDEN TESTS
test_rng = np.random.default_rng(510)  # the tests' own draws, not the notebook's rng
for _ in range(5):
    Wr = test_rng.normal(size=(4, 3, 3)) * 3
    pr = test_rng.random(4)
    Er = np.exp(np.maximum(np.tensordot(pr, Wr, axes=1), 0.0))
    got, expected = np.asarray(transition_matrix(pr, Wr)), Er / Er.sum(axis=0)
    assert got.shape == expected.shape and np.allclose(got, expected), (
        f"random W (4, 3, 3) and p = {np.round(pr, 3)}: expected T = "
        f"{np.round(expected, 4).tolist()}; got {np.round(got, 4).tolist()}")
big = np.asarray(transition_matrix(np.ones(1), np.full((1, 3, 3), 1000.0) + np.eye(3)))
assert np.all(np.isfinite(big)) and np.allclose(big.sum(axis=0), 1.0), (
    f"logits of 1000 (subtract each column's maximum before np.exp): expected finite columns "
    f"summing to one; got {np.round(big, 4).tolist()}")
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
assert out.shape == (5, 4), f"expected shape (B, N) = (5, 4); got {out.shape}"
assert np.allclose(out.sum(axis=1), 1.0), (
    f"B = 5: expected every row (a distribution) to sum to one; got row sums {out.sum(1)}")
row2 = vagn.transition_matrix(pb[2], Wb) @ qb[2]
assert np.allclose(out[2], row2), (
    f"sample 2: expected T(p[2]) @ q[2] = {np.round(row2, 4)} (T acts on a column vector: "
    f"q_t = T q_(t-1)); got {np.round(out[2], 4)}")
### BEGIN HIDDEN TESTS
for i in range(5):
    row = vagn.transition_matrix(pb[i], Wb) @ qb[i]
    assert np.allclose(out[i], row), (
        f"sample {i}, with its own predicates: expected T(p[{i}]) @ q[{i}] = {np.round(row, 4)}; "
        f"got {np.round(out[i], 4)}")
flat = np.asarray(vagn_step(np.eye(4), np.zeros((4, 3)), Wb))
assert np.allclose(flat, 0.25), (
    f"p = 0 (uniform columns), one-hot starts: expected every row [0.25] * 4; got "
    f"{np.round(flat, 4).tolist()}")
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 5.3 — the stationary distribution
# For a column-stochastic `T` with positive entries, return the unique
# distribution $\pi$ with $T\pi = \pi$, entries summing to one.
#
# `vagn.stationary_distribution` is switched off while this exercise is graded.
#
# <details><summary>Hint 1 (the idea)</summary>
#
# $T\pi = \pi$ says that π is an eigenvector of $T$. Of which eigenvalue? Why
# does every column-stochastic matrix have that eigenvalue (look at
# $\mathbf 1^\top T$), and why is its eigenvector unique here (every entry of a
# vAGN `T` is positive: Perron–Frobenius)?
# </details>
#
# <details><summary>Hint 2 (the method)</summary>
#
# An eigen-solver returns the eigenvalues in no particular order and each
# eigenvector with unit length, an arbitrary sign and a complex dtype: select
# the right one by its eigenvalue, not by its position, then scale it so that
# its entries sum to one. If your result has huge entries of both signs, you
# picked an eigenvector whose entries sum to zero — why must every other
# eigenvector's entries sum to zero? (Iterating $q \leftarrow Tq$ also works.)
# </details>

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
assert np.allclose(pi, [0.25, 0.75]), (
    f"for T = [[0.7, 0.1], [0.3, 0.9]] expected pi = [0.25, 0.75] (b / (a + b), a / (a + b)); "
    f"got {pi} — did you take the eigenvector of eigenvalue 1?")
T3 = vagn.transition_matrix(rng.random(3), rng.normal(size=(3, 3, 3)))
pi3 = stationary(T3)
assert np.isclose(pi3.sum(), 1.0), f"a random 3-state T: expected sum(pi) = 1; got {pi3.sum()}"
assert np.allclose(T3 @ pi3, pi3), (
    f"a random 3-state T: expected T pi = pi; got T pi - pi = {T3 @ pi3 - pi3}")
### BEGIN HIDDEN TESTS
test_rng = np.random.default_rng(530)  # the tests' own draws, not the notebook's rng
T5 = vagn.transition_matrix(test_rng.random(2), test_rng.normal(size=(2, 5, 5)) * 2)
pi5 = np.asarray(stationary(T5))
assert np.allclose(T5 @ pi5, pi5) and np.isclose(pi5.sum(), 1.0), (
    f"a random 5-state T: expected T pi = pi and sum(pi) = 1; got T pi - pi = "
    f"{np.round(T5 @ pi5 - pi5, 4)}, sum {pi5.sum():.4f}")
assert np.all(pi5 > 0), (
    f"a random 5-state T (Perron–Frobenius): expected every entry of pi > 0; got {pi5}")
pi_c = stationary(np.array([[0.5, 0.25, 0.0], [0.5, 0.5, 0.5], [0.0, 0.25, 0.5]]))
assert np.allclose(pi_c, [0.25, 0.5, 0.25]), (
    f"the 3-state chain [[.5, .25, 0], [.5, .5, .5], [0, .25, .5]]: expected pi = "
    f"[0.25, 0.5, 0.25]; got {pi_c}")
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 5.4 — Viterbi: the most likely q-path
# The per-step argmax of the marginals $q_t$ answers "which state is most
# probable at time $t$"; the most probable **sequence** $s_0, \dots, s_T$ is a
# different question, and the two can disagree. A path's log-probability is
#
# $$\log P(s_{0:T}) = \log q_0[s_0] + \sum_{t=1}^{T} \log T_t[s_t, s_{t-1}],$$
#
# with `Ts[t - 1]` the matrix $T_t$ of step $t$ (shape `(T, N, N)`, columns sum
# to one, rows are "to"). Dynamic programming finds the best of the $N^{T+1}$
# paths in $O(T N^2)$: $\delta_0 = \log q_0$,
# $\delta_t[i] = \max_j \big(\log T_t[i, j] + \delta_{t-1}[j]\big)$, remembering
# the maximising $j$ as a back-pointer; the path ends in $\arg\max_i \delta_T[i]$
# and is traced back. Return `(path, logp)`: an integer array of length $T + 1$
# and a float.

# %% solution id=ex05_4 title="Viterbi decoding" forbids="minimanc.vagn.most_likely_path"
def viterbi(q0, Ts):
    ### BEGIN SOLUTION
    logT = np.log(np.asarray(Ts, float))
    delta = np.log(np.asarray(q0, float))
    back = []
    for t in range(logT.shape[0]):
        scores = logT[t] + delta[None, :]          # scores[i, j]: arrive in i from j
        back.append(np.argmax(scores, axis=1))
        delta = np.max(scores, axis=1)
    path = [int(np.argmax(delta))]
    for b in reversed(back):
        path.append(int(b[path[-1]]))
    return np.array(path[::-1]), float(np.max(delta))
    ### END SOLUTION

# %%
def path_logp(q0, Ts, path):
    """Log-probability of one path (the formula above)."""
    return np.log(q0[path[0]]) + sum(np.log(Ts[t, path[t + 1], path[t]]) for t in range(len(Ts)))


def brute_force_path(q0, Ts):
    """Try all N^(T+1) paths (an independent oracle for small N and T)."""
    paths = list(itertools.product(range(len(q0)), repeat=len(Ts) + 1))
    scores = [path_logp(q0, Ts, s) for s in paths]
    return np.array(paths[int(np.argmax(scores))]), float(np.max(scores))

# %% grade id=ex05_4_tests points=3
# Two states: the per-step argmax of the marginals is 0, 1, 0 (a path of probability
# 0.6 · 0.5 · 0.4 = 0.12), but the most likely path is 0, 0, 0 (probability 0.3).
q0_v = np.array([0.6, 0.4])
Ts_v = np.array([[[0.5, 0.0001], [0.5, 0.9999]],    # from 0: a coin flip; from 1: stay
                 [[1.0 - 1e-9, 0.4], [1e-9, 0.6]]])  # from 0: stay; from 1: 0.4 to state 0
path_v, logp_v = viterbi(q0_v, Ts_v)
assert len(path_v) == 3, f"a path over T = 2 steps has T + 1 = 3 states; got {path_v}"
assert list(path_v) == [0, 0, 0], f"expected the path [0, 0, 0] (probability 0.3); got {path_v}"
assert np.isclose(logp_v, np.log(0.6 * 0.5 * (1 - 1e-9))), (
    f"expected log(0.6 · 0.5 · (1 - 1e-9)) = {np.log(0.3):.4f}; got {logp_v}")
### BEGIN HIDDEN TESTS
rng_v = np.random.default_rng(54)
for trial in range(20):
    Wv = rng_v.normal(size=(2, 3, 3)) * 2.5
    Ts_r = vagn.transition_matrix(rng_v.random((4, 2)), Wv)        # N = 3, T = 4
    q0_r = rng_v.dirichlet(np.ones(3))
    want_path, want_logp = brute_force_path(q0_r, Ts_r)
    got_path, got_logp = viterbi(q0_r, Ts_r)
    assert np.isclose(got_logp, want_logp), (
        f"trial {trial}: the best of all 243 paths has log-probability {want_logp:.6f}; "
        f"got {got_logp}")
    assert np.isclose(path_logp(q0_r, Ts_r, got_path), want_logp), (
        f"trial {trial}: the returned path {got_path} does not have the returned "
        f"log-probability (best path {want_path})")
    kind = np.asarray(got_path).dtype
    assert kind.kind == "i", f"trial {trial}: expected integer state indices; got dtype {kind}"
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 5.5 — Algorithm 1: every sample starts from a uniform q
# Algorithm 1 trains on a minibatch of $m$ samples. The true q-state of a human
# driver is never known, so **each sample** starts its own run of vAGN from
# $q' = \texttt{UniformInit}() = (1/N, \dots, 1/N)$; nothing of one sample's q
# may leak into another's. Write `run_minibatch(ps, W, xp=np)` for `ps` of
# shape `(B, T, M)` (batch-major, as a data loader yields it): every sample
# starts from the uniform q and consumes its own $T$ predicate vectors with
# eq. 9; return the final q of every sample, shape `(B, N)`.
#
# Write it with `xp` operations only (`xp.ones`, `xp.sum`, `xp.expand_dims`,
# arithmetic, indexing of `ps`), so that `engine("numpy")` can differentiate it;
# `vagn.transition_matrix(p, W, xp=xp)` accepts a batch `p` of shape `(B, M)`.
# `vagn.rollout` is disabled while this exercise is graded.

# %% solution id=ex05_5 title="Algorithm 1's minibatch with uniform starts" forbids="minimanc.vagn.rollout"  # noqa: E501
def run_minibatch(ps, W, xp=np):
    ### BEGIN SOLUTION
    B, T_len, _ = np.shape(ps)
    N = W.shape[-1]
    q = xp.ones((B, N)) / N                       # UniformInit(), once per sample
    for t in range(T_len):
        T = vagn.transition_matrix(ps[:, t], W, xp=xp)      # (B, N, N)
        q = xp.sum(T * xp.expand_dims(q, -2), axis=-1)      # q_t = T q_{t-1}, per sample
    return q
    ### END SOLUTION

# %% grade id=ex05_5_tests points=3
rng_m = np.random.default_rng(55)
Wm = rng_m.normal(size=(2, 3, 3)) * 2.0
ps_m = rng_m.random((6, 5, 2))                     # B = 6 samples, T = 5 steps, M = 2
out_m = run_minibatch(ps_m, Wm)
assert np.shape(out_m) == (6, 3), f"expected the final q of each sample, shape (6, 3); got {np.shape(out_m)}"  # noqa: E501
assert np.allclose(np.sum(out_m, axis=1), 1.0), (
    f"B = 6: expected every final q to sum to one; got {np.round(np.sum(out_m, axis=1), 4)}")
rev_m = np.asarray(run_minibatch(ps_m[::-1], Wm))[::-1]
assert np.allclose(rev_m, out_m), (
    f"the samples in reverse order must give the results in reverse order (each sample "
    f"starts from its own uniform q, nothing carries over): sample 0 gave "
    f"{np.round(out_m[0], 4)} in order and {np.round(rev_m[0], 4)} reversed")
one = np.asarray(run_minibatch(ps_m[:, :1], Wm))
rows = vagn.transition_matrix(ps_m[:, 0], Wm).mean(axis=-1)
assert np.allclose(one, rows), (
    f"one step from the uniform q: expected q_1 = T(p_1) (1/N, ..., 1/N), the row means of "
    f"T: {np.round(rows[0], 4)} for sample 0; got {np.round(one[0], 4)}")
### BEGIN HIDDEN TESTS
for b in range(6):
    q_ref = np.full(3, 1.0 / 3)
    for t in range(5):
        q_ref = vagn.transition_matrix(ps_m[b, t], Wm) @ q_ref
    assert np.allclose(out_m[b], q_ref), (
        f"sample {b}: expected {q_ref} (eq. 9 five times from the uniform q); got {out_m[b]}")
    assert np.allclose(run_minibatch(ps_m[b:b + 1], Wm)[0], q_ref), (
        f"sample {b} alone: expected {q_ref} (as inside the minibatch); got "
        f"{run_minibatch(ps_m[b:b + 1], Wm)[0]}")
eng_m = engine("numpy")
g_m = eng_m.grad(lambda W: eng_m.xp.sum(run_minibatch(ps_m, W, xp=eng_m.xp)[:, 0]))(Wm)
E_m = np.zeros_like(Wm)
E_m[1, 0, 2] = 1e-6
fd = (run_minibatch(ps_m, Wm + E_m)[:, 0].sum() - run_minibatch(ps_m, Wm - E_m)[:, 0].sum()) / 2e-6
assert np.shape(g_m) == Wm.shape and np.isclose(g_m[1, 0, 2], fd, rtol=1e-5, atol=1e-9), (
    f"engine('numpy') gradient of sum q[:, 0] with respect to W[1, 0, 2] (use xp operations "
    f"only): expected {fd:.6g} (central difference); got "
    f"{np.asarray(g_m)[1, 0, 2] if np.shape(g_m) == Wm.shape else np.shape(g_m)}")
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 5.6 — learning W from the actions alone
# The tutorial fits $W$ to known q-targets. The paper never sees q: it trains
# vAGN only through the **action** that the DMP produces from q. Here the
# action is a speed. Each q-state $j$ has a goal speed $G_j$ (cruise fast,
# follow slower, yield stop); after vAGN step $t$ the DMP's goal is the
# q-weighted goal $g_t = \sum_j q_t[j]\, G_j$, and the speed $y$ (with its rate
# $\dot y$, starting at 0) takes one semi-implicit DMP step of `H_S` toward it
# (chapter 3, eq. 10, gains `ALPHA_S`, `BETA_S`):
#
# $$\dot y \leftarrow \dot y + h\,\alpha\big(\beta(g_t - y) - \dot y\big), \qquad
#   y \leftarrow y + h\,\dot y .$$
#
# 1. `dmp_speeds(ps, W, q0, y0, G, xp=np)`: `ps` time-major `(T, B, M)`, `q0`
#    `(B, N)`, `y0` `(B,)`, `G` `(N,)`; return the speeds $y_0, \dots, y_T$,
#    shape `(T + 1, B)`. Use `xp` operations only (`vagn.rollout(..., xp=xp)`
#    is allowed), so that `engine("numpy")` can differentiate it.
# 2. `fit_W_from_speeds(ps, target, q0, y0, G, W0, steps, lr)`: starting from
#    `W0` (not modified), take `steps` **Adam** steps (`optim.adam_init`,
#    `optim.adam_update`, chapter 2) on the mean squared error of the speeds
#    $y_1, \dots, y_T$ against `target[1:]`, with the gradient from
#    `engine("numpy")`. Return `(W, losses)`, the loss before each update.
#    The speeds come from `speeds(ps, W, q0, y0, G, xp=...)`, by default your
#    `dmp_speeds` (the tests pass their own, so that 2 does not depend on 1).
#
# The two functions are graded separately, 2 points each. The hidden tests
# also check what the paper claims: that the automaton learned from speeds
# alone puts its probability in the teacher's states.
#
# <details><summary>Hint 1 (the idea)</summary>
#
# The q-sequence is what `vagn.rollout` returns; the speed is chapter 3's DMP
# driven by a goal that changes every step. The loss never mentions q.
# </details>
#
# <details><summary>Hint 2 (the method)</summary>
#
# Keep the speeds in a Python list and `xp.stack` them at the end (no in-place
# assignment under autodiff); $g_t$ is a sum over the last axis of `qs[t] * G`.
# Adam's state starts from `W0` and is threaded through the loop.
# </details>

# %%
ALPHA_S, BETA_S, H_S = 4.0, 1.0, 0.25   # stable: 4 < 4 / (h (2 + h beta)) = 7.1


def sample_predicates(rng, T, B, M=3):
    """Piecewise-constant random predicate sequences in [0, 1], shape (T, B, M)."""
    ps = np.zeros((T, B, M))
    for b in range(B):
        t = 0
        while t < T:
            d = rng.integers(3, 8)
            ps[t:t + d, b] = rng.random(M) * (rng.random(M) < 0.6)
            t += d
    return ps


W_true = np.zeros((3, 3, 3))      # chapter 5's cruise / follow / yield automaton
W_true[0, 0, :] = 3.0
W_true[1, 1, :] = 3.0
W_true[2, 2, :] = 4.0
W_true[2, 0, :] = -3.0
W_true += np.eye(3)[None]
G_SPEED = np.array([1.0, 0.5, 0.0])    # goal speeds (x 10 m/s): cruise, follow, yield

# %% solution id=ex05_6 title="Learn W from the DMP's speeds alone"
def dmp_speeds(ps, W, q0, y0, G, xp=np):
    ### BEGIN SOLUTION
    qs = vagn.rollout(q0, ps, W, xp=xp)
    y, rate, speeds = y0, 0.0 * y0, [y0]
    for t in range(1, qs.shape[0]):
        goal = xp.sum(qs[t] * G, axis=-1)
        rate = rate + H_S * ALPHA_S * (BETA_S * (goal - y) - rate)
        y = y + H_S * rate
        speeds.append(y)
    return xp.stack(speeds)
    ### END SOLUTION


def fit_W_from_speeds(ps, target, q0, y0, G, W0, steps=300, lr=0.1, speeds=dmp_speeds):
    ### BEGIN SOLUTION
    eng = engine("numpy")
    mse = eng.value_and_grad(
        lambda W: eng.xp.mean((speeds(ps, W, q0, y0, G, xp=eng.xp)[1:] - target[1:]) ** 2))
    W = np.array(W0, dtype=float)
    state, losses = optim.adam_init(W), []
    while len(losses) < steps:
        value, grad = mse(W)
        losses.append(float(value))
        W, state = optim.adam_update(grad, state, W, lr=lr)
    return W, losses
    ### END SOLUTION

# %% grade id=ex05_6_speeds_tests points=2
ps6 = np.zeros((3, 1, 3))
ps6[:, 0, 0] = 1.0                               # road clear for three steps
q06, y06 = vagn.uniform_state(3)[None], np.array([0.2])
y6 = np.asarray(dmp_speeds(ps6, W_true, q06, y06, G_SPEED))
assert np.shape(y6) == (4, 1), f"T = 3 steps, B = 1: expected shape (4, 1); got {np.shape(y6)}"
assert np.isclose(y6[0, 0], 0.2), f"y_0 is y0 = 0.2; got {y6[0, 0]!r}"
g61 = vagn.rollout(q06, ps6, W_true)[1, 0] @ G_SPEED
assert np.isclose(y6[1, 0], 0.2 + 0.25 ** 2 * 4.0 * (g61 - 0.2)), (
    f"road clear, from y0 = 0.2 at rest: the goal after step 1 is {g61:.4f}; expected "
    f"y_1 = {0.2 + 0.25 ** 2 * 4.0 * (g61 - 0.2):.4f}; got {y6[1, 0]:.4f}")
### BEGIN HIDDEN TESTS
test_rng = np.random.default_rng(560)  # the tests' own draws, not the notebook's rng
psr = sample_predicates(test_rng, 12, 5)
q0r, y0r = vagn.random_state(test_rng, 3, size=5), test_rng.uniform(0, 1, 5)
Wr = test_rng.normal(size=(3, 3, 3)) * 2
got = np.asarray(dmp_speeds(psr, Wr, q0r, y0r, G_SPEED))
qr = vagn.rollout(q0r, psr, Wr)
yr, vr, ref = y0r.copy(), np.zeros(5), [y0r.copy()]
for t in range(1, 13):                           # written out, one sub-step per step
    vr = vr + 0.25 * 4.0 * (1.0 * (qr[t] @ G_SPEED - yr) - vr)
    yr = yr + 0.25 * vr
    ref.append(yr)
ref = np.array(ref)
assert got.shape == (13, 5), f"T = 12, B = 5: expected shape (13, 5); got {got.shape}"
worst = np.unravel_index(np.argmax(np.abs(got - ref)), ref.shape)
assert np.allclose(got, ref, rtol=1e-10, atol=1e-12), (
    f"random W, q0 and y0: at step {worst[0]}, sample {worst[1]} expected speed "
    f"{ref[worst]:.6f}, got {got[worst]:.6f}")
eng6 = engine("numpy")
g6 = eng6.grad(lambda W: eng6.xp.sum(dmp_speeds(psr, W, q0r, y0r, G_SPEED, xp=eng6.xp)))(Wr)
E6 = np.zeros_like(Wr)
E6[0, 1, 2] = 1e-6
fd6 = (np.sum(dmp_speeds(psr, Wr + E6, q0r, y0r, G_SPEED))
       - np.sum(dmp_speeds(psr, Wr - E6, q0r, y0r, G_SPEED))) / 2e-6
assert np.shape(g6) == Wr.shape and np.isclose(g6[0, 1, 2], fd6, rtol=1e-5, atol=1e-9), (
    f"d sum(speeds) / dW[0, 1, 2] with engine('numpy'): expected {fd6:.6g} (central "
    f"difference); got {np.asarray(g6)[0, 1, 2] if np.shape(g6) == Wr.shape else g6}")
### END HIDDEN TESTS

# %% grade id=ex05_6_fit_tests points=2
# the speeds are the tests' own (passed as `speeds=`), so this does not depend on dmp_speeds
rng_f = np.random.default_rng(56)
ps_f = sample_predicates(rng_f, 16, 32)
q0_f, y0_f = np.tile(vagn.uniform_state(3), (32, 1)), rng_f.uniform(0, 1, 32)


def reference_speeds(ps, W, q0, y0, G, xp=np):
    qs, y, v, out = vagn.rollout(q0, ps, W, xp=xp), y0, 0.0 * y0, [y0]
    for t in range(1, qs.shape[0]):
        v = v + H_S * ALPHA_S * (BETA_S * (xp.sum(qs[t] * G, axis=-1) - y) - v)
        y = y + H_S * v
        out.append(y)
    return xp.stack(out)


target_f = reference_speeds(ps_f, W_true, q0_f, y0_f, G_SPEED)
W0_f = vagn.init_vagn(rng_f, 3, 3, scale=0.1, mean=0.5)
W0_copy = W0_f.copy()
W_f, losses_f = fit_W_from_speeds(ps_f, target_f, q0_f, y0_f, G_SPEED, W0_f, steps=300, lr=0.1,
                                  speeds=reference_speeds)
assert len(losses_f) == 300, f"300 steps: expected 300 losses; got {len(losses_f)}"
assert np.shape(W_f) == (3, 3, 3), f"expected W of shape (3, 3, 3); got {np.shape(W_f)}"
assert losses_f[-1] < 1e-3 and losses_f[-1] < 0.05 * losses_f[0], (
    f"300 Adam steps of lr 0.1: expected the speed loss below 1e-3 and 5 % of its start "
    f"({losses_f[0]:.4f}); got {losses_f[-1]:.2e}")
### BEGIN HIDDEN TESTS
assert np.array_equal(W0_f, W0_copy), (
    "expected W0 unchanged after fit_W_from_speeds; got W0 modified in place")
final = np.mean((reference_speeds(ps_f, W_f, q0_f, y0_f, G_SPEED)[1:] - target_f[1:]) ** 2)
assert final <= losses_f[-1] * 1.5 + 1e-6, (
    f"the returned W must be the trained one: expected its loss at most about the last "
    f"recorded {losses_f[-1]:.2e}; got {final:.2e}")
test_rng = np.random.default_rng(561)  # held-out scenes, the tests' own draws
ps_h = sample_predicates(test_rng, 16, 64)
q0_h = np.tile(vagn.uniform_state(3), (64, 1))
same = np.mean(vagn.rollout(q0_h, ps_h, W_f)[1:].argmax(-1)
               == vagn.rollout(q0_h, ps_h, W_true)[1:].argmax(-1))
assert same > 0.9, (
    f"held-out scenes: expected the learned automaton's most probable state to be the "
    f"teacher's in more than 90 % of the steps (the paper's claim); got {same:.2f}")
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 5.7 — open experiment: does q recover the teacher's states?
# 5.6 checked the speeds; the paper's central claim is about q: trained only
# through the action, the automaton's states should *mean* something — here,
# be the teacher's states. Test it, and find where it breaks.
#
# 1. `state_agreement(W, W_ref, ps, q0)`: roll both automata out from `q0`
#    over `ps` (`vagn.rollout`) and return the fraction of the steps
#    $t = 1, \dots, T$ and samples in which their most probable state is the
#    same, a float in [0, 1]. (1 point)
# 2. `blind_experiment()`, returning `(G_blind, W_distinct, W_blind)` (2 points):
#    train `W_distinct` with your `fit_W_from_speeds`
#    on the teacher's speeds with `G_SPEED` (use `ps_train`, `q0_train`,
#    `y0_train` below, 300 steps, lr 0.1). Then **choose** goal speeds
#    `G_blind` (shape `(3,)`, values in [0, 1], not all three equal, so that
#    the speed still depends on the state) for which you expect the speeds
#    *not* to identify the states, make the teacher's speeds with `G_blind`,
#    and train `W_blind` on them the same way. The tests roll your two automata
#    out on held-out scenes of their own: `W_distinct` must agree with the
#    teacher in more than 90 % of the steps; `W_blind` must still fit its
#    speeds (held-out speed error below 1e-3) but agree in fewer than 85 %.
#
# Then answer the written question below the grade cells.

# %%
rng_x = np.random.default_rng(58)
ps_train = sample_predicates(rng_x, 16, 64)
q0_train, y0_train = np.tile(vagn.uniform_state(3), (64, 1)), rng_x.uniform(0, 1, 64)
W0_train = vagn.init_vagn(rng_x, 3, 3, scale=0.1, mean=0.5)

# %% solution id=ex05_7 title="Open experiment: do the learned states mean the teacher's?"
def state_agreement(W, W_ref, ps, q0):
    ### BEGIN SOLUTION
    a = vagn.rollout(q0, ps, W)[1:].argmax(axis=-1)
    b = vagn.rollout(q0, ps, W_ref)[1:].argmax(axis=-1)
    return float(np.mean(a == b))
    ### END SOLUTION


def blind_experiment():
    ### BEGIN SOLUTION
    speeds_distinct = dmp_speeds(ps_train, W_true, q0_train, y0_train, G_SPEED)
    W_distinct, _ = fit_W_from_speeds(ps_train, speeds_distinct, q0_train, y0_train, G_SPEED,
                                      W0_train, steps=300, lr=0.1)
    G_blind = np.array([1.0, 0.5, 0.5])      # follow and yield ask for the same speed
    speeds_blind = dmp_speeds(ps_train, W_true, q0_train, y0_train, G_blind)
    W_blind, _ = fit_W_from_speeds(ps_train, speeds_blind, q0_train, y0_train, G_blind,
                                   W0_train, steps=300, lr=0.1)
    return G_blind, W_distinct, W_blind
    ### END SOLUTION

# %% grade id=ex05_7_agreement_tests points=1
one = state_agreement(W_true, W_true, ps_train, q0_train)
assert np.isclose(one, 1.0), f"an automaton against itself: expected 1.0; got {one!r}"
### BEGIN HIDDEN TESTS
test_rng = np.random.default_rng(570)  # the tests' own draws, not the notebook's rng
for _ in range(5):
    Wa, Wb = test_rng.normal(size=(2, 3, 3, 3)) * 2
    ps_a, q0_a = sample_predicates(test_rng, 10, 7), vagn.random_state(test_rng, 3, size=7)
    expected = np.mean(vagn.rollout(q0_a, ps_a, Wa)[1:].argmax(-1)
                       == vagn.rollout(q0_a, ps_a, Wb)[1:].argmax(-1))
    got = state_agreement(Wa, Wb, ps_a, q0_a)
    assert type(got) is float and np.isclose(got, expected), (
        f"two random automata, T = 10, B = 7: expected the float {expected:.4f} (steps "
        f"1..T only, q0 excluded); got {got!r}")
### END HIDDEN TESTS

# %% grade id=ex05_7_tests points=2
G_blind, W_distinct, W_blind = blind_experiment()   # two trainings, about 10 s
G_b = np.asarray(G_blind, dtype=float)
assert G_b.shape == (3,) and np.all((G_b >= 0) & (G_b <= 1)) and np.ptp(G_b) > 0, (
    f"G_blind: expected 3 goal speeds in [0, 1], not all equal; got {G_blind!r}")
### BEGIN HIDDEN TESTS
test_rng = np.random.default_rng(571)  # held-out scenes, the tests' own draws
ps_h = sample_predicates(test_rng, 16, 64)
q0_h, y0_h = np.tile(vagn.uniform_state(3), (64, 1)), test_rng.uniform(0, 1, 64)


def agree(W):
    return np.mean(vagn.rollout(q0_h, ps_h, W)[1:].argmax(-1)
                   == vagn.rollout(q0_h, ps_h, W_true)[1:].argmax(-1))


def speed_error(W, G):   # the speeds written out, not your dmp_speeds
    out = []
    for Wx in (W, W_true):
        qs, y, v, ys = vagn.rollout(q0_h, ps_h, Wx), y0_h, np.zeros(64), []
        for t in range(1, len(qs)):
            v = v + H_S * ALPHA_S * (BETA_S * (qs[t] @ G - y) - v)
            y = y + H_S * v
            ys.append(y)
        out.append(np.array(ys))
    return np.mean((out[0] - out[1]) ** 2)


a_d, a_b = agree(np.asarray(W_distinct)), agree(np.asarray(W_blind))
assert a_d > 0.9, (
    f"W_distinct on held-out scenes: expected the teacher's most probable state in more "
    f"than 90 % of the steps; got {a_d:.2f}")
err_b = speed_error(np.asarray(W_blind), G_b)
assert err_b < 1e-3, (
    f"W_blind with G_blind = {np.round(G_b, 3).tolist()}: expected held-out speeds within "
    f"a mean squared error of 1e-3 of the teacher's; got {err_b:.2e} (train it on speeds "
    f"made with G_blind)")
assert a_b < 0.85, (
    f"G_blind = {np.round(G_b, 3).tolist()}: expected the speeds not to identify the "
    f"states (agreement below 0.85); got {a_b:.2f}")
### END HIDDEN TESTS

# %% [markdown]
# **Written question (5.7).** Why do the speeds identify the teacher's states
# with `G_SPEED` but not with your `G_blind`? What does this say about the
# paper's claim that vAGN's q-states become interpretable when they are learned
# only through the action loss? Name one change to the action model (not to
# the data) that would make your `G_blind` experiment identifiable again.

# %% [markdown] answer id=ex05_7_w title="When the action identifies the states" points=3
# ### BEGIN SOLUTION
# The loss sees q only through the scalar goal g_t = Σ_j q_t[j] G_j. With
# distinct goal speeds each state changes the speed differently, so the only
# way to reproduce the teacher's speeds over many scenes is (nearly) the
# teacher's q, and the argmax agrees in ≈ 99 % of the steps. With
# G_blind = (1, 0.5, 0.5) *follow* and *yield* ask for the same speed: any split
# of their mass gives the same g_t, the speeds fit as well (held-out error
# ≈ 1e-5) and the learned automaton labels the two states arbitrarily
# (agreement ≈ 0.4). The paper's claim holds only as far as the action
# distinguishes the states: q-states are interpretable when they *do*
# different things; states with the same action are not identifiable from
# behaviour cloning, whatever their meaning for a human. (Even with distinct
# goals one scalar per step leaves a two-dimensional q underdetermined at a
# single step; it is the dynamics over many scenes that pins it down, and a
# small data set can end in a local minimum: B = 32 with another seed gave
# 0.72.) A fix in the action model: give each state its own *vector* of
# actions — e.g. a goal speed and a goal yaw (or different gains α_j, β_j per
# state, as MANC's head outputs them), so that no two states produce the same
# action.
# ### END SOLUTION

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

# %% [markdown]
# ## Your figure
# Top: **your** `transition_matrix` draws the automaton under each predicate
# (tutorial section 1): the arrows must match the library's. Bottom: q on the
# tutorial's drive for the teacher and for **your** `W_distinct` and `W_blind`
# of 5.7, learned from speeds only: with distinct goal speeds the learned q
# should look like the teacher's, with `G_blind` it need not. A function that
# raises (or a result not made yet) is named, and the library's reference drawn.

# %%
STATES, PREDICATES = ["cruise", "follow", "yield"], ["road clear", "lead close", "crossing"]
drive = np.zeros((30, 3))
drive[:, 0] = 1.0
drive[8:18, 1] = np.minimum(1.0, np.arange(1, 11) / 4)
drive[8:18, 0] = 1.0 - drive[8:18, 1]
drive[20:25, 2], drive[20:25, 0] = 1.0, 0.0
q_teacher = vagn.rollout(vagn.uniform_state(3), drive, W_true)


def q_of(name):
    """q on the drive for the automaton this notebook bound to ``name`` (5.7)."""
    if name not in globals():
        raise NotImplementedError(f"{name} comes from 5.7's grade cell (blind_experiment)")
    return vagn.rollout(vagn.uniform_state(3), drive, np.asarray(globals()[name]))


print("teacher's most probable states:", "".join("CFY"[s] for s in q_teacher.argmax(-1)))
assert q_teacher[15].argmax() == 1 and q_teacher[23].argmax() == 2
fig, axes = plt.subplots(2, 3, figsize=(12, 7.5))
plot_automaton_attempts(
    [(f"only '{name}'", "T", lambda p=p: transition_matrix(p, W_true),
      vagn.transition_matrix(p, W_true)) for p, name in zip(np.eye(3), PREDICATES)],
    labels=STATES, axes=axes[0])
plot_q_heatmap(q_teacher, ax=axes[1, 0], labels=STATES, colorbar=False)
axes[1, 0].set_title("q: the teacher (library)")
plot_automaton_attempts([("q: W_distinct", "q", lambda: q_of("W_distinct"), None),
                         ("q: W_blind", "q", lambda: q_of("W_blind"), None)],
                        labels=STATES, axes=axes[1, 1:])
plt.tight_layout()
plt.show()
