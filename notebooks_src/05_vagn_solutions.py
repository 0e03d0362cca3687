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
assert T.shape == (2, 2), f"expected T of shape (N, N) = (2, 2); got {T.shape}"
assert np.allclose(T.sum(axis=0), 1.0), f"every column must sum to one; column sums {T.sum(0)}"
assert np.isclose(T[0, 0], np.exp(2) / (np.exp(2) + 1)), (
    f"T[0, 0] = e^2 / (e^2 + e^0) = 0.8808 (softmax along the column); got {T[0, 0]:.4f}")
assert np.allclose(T[:, 1], 0.5), f"ReLU(-1) = 0 and e^0 = 1: column 1 is [0.5, 0.5]; got {T[:, 1]}"
### BEGIN HIDDEN TESTS
for _ in range(5):
    Wr = rng.normal(size=(4, 3, 3)) * 3
    pr = rng.random(4)
    Er = np.exp(np.maximum(np.tensordot(pr, Wr, axes=1), 0.0))
    assert np.allclose(transition_matrix(pr, Wr), Er / Er.sum(axis=0)), (
        "T must equal exp(ReLU(sum_i p_i W_i)) / column sums for random W and p")
big = transition_matrix(np.ones(1), np.full((1, 3, 3), 1000.0) + np.eye(3))
assert np.all(np.isfinite(big)) and np.allclose(big.sum(axis=0), 1.0), (
    "logits of 1000 must not overflow: subtract each column's maximum before np.exp")
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
assert np.allclose(out.sum(axis=1), 1.0), f"q must stay a distribution; row sums {out.sum(1)}"
assert np.allclose(out[2], vagn.transition_matrix(pb[2], Wb) @ qb[2]), (
    "row 2 must be T(p[2]) @ q[2] (T acts on a column vector: q_t = T q_{t-1})")
### BEGIN HIDDEN TESTS
assert np.allclose(out, [vagn.transition_matrix(pb[i], Wb) @ qb[i] for i in range(5)]), (
    "every row b must be T(p[b]) @ q[b], each sample with its own predicates")
assert np.allclose(vagn_step(np.eye(4), np.zeros((4, 3)), Wb), 0.25), (
    "p = 0 gives uniform columns, so every start goes to the uniform distribution")
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 5.3 — the stationary distribution
# For a column-stochastic `T` with positive entries, return the unique
# distribution $\pi$ with $T\pi = \pi$, entries summing to one.
#
# **Hint — which eigenvector.** $\pi$ is the eigenvector of the eigenvalue
# $\lambda = 1$. Every column-stochastic matrix has it ($\mathbf 1^\top T =
# \mathbf 1^\top$), and because every entry of a vAGN `T` is positive,
# Perron–Frobenius says this eigenvalue is simple, every other eigenvalue has
# $|\lambda| < 1$, and its eigenvector can be scaled to have all entries
# positive. `np.linalg.eig` returns the eigenvalues **in no particular order**,
# so `vecs[:, 0]` is not necessarily the one you want: pick the column
# `np.argmin(np.abs(vals - 1))`. The eigenvector comes with unit length, an
# arbitrary sign and a complex dtype: take the real part and divide by its
# sum. (Dividing the wrong eigenvector by its sum gives nonsense like
# `[6.4e15, -6.4e15]`: for $\lambda \ne 1$, $\mathbf 1^\top v = \mathbf 1^\top T v
# = \lambda\, \mathbf 1^\top v$ forces $\mathbf 1^\top v = 0$.) Iterating
# $q \leftarrow T q$ until it stops changing also works.

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
assert np.isclose(pi3.sum(), 1.0), f"pi must sum to one; got sum {pi3.sum()}"
assert np.allclose(T3 @ pi3, pi3), f"pi must satisfy T pi = pi; got T pi - pi = {T3 @ pi3 - pi3}"
### BEGIN HIDDEN TESTS
T5 = vagn.transition_matrix(rng.random(2), rng.normal(size=(2, 5, 5)) * 2)
pi5 = stationary(T5)
assert np.allclose(T5 @ pi5, pi5) and np.isclose(pi5.sum(), 1.0), (
    "for a random 5-state T, pi must satisfy T pi = pi and sum to one")
assert np.all(pi5 > 0), f"Perron–Frobenius: every entry of pi is positive; got {pi5}"
assert np.allclose(stationary(np.array([[0.5, 0.25, 0.0], [0.5, 0.5, 0.5], [0.0, 0.25, 0.5]])),
                   [0.25, 0.5, 0.25]), "expected pi = [0.25, 0.5, 0.25] for the 3-state chain"
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
import itertools


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
marg = [q0_v, Ts_v[0] @ q0_v, Ts_v[1] @ Ts_v[0] @ q0_v]
assert [int(np.argmax(m)) for m in marg] == [0, 1, 0], "the marginals' argmax is 0, 1, 0"
assert not np.array_equal(path_v, [0, 1, 0]), (
    "Viterbi maximises over whole paths; the per-step argmax 0, 1, 0 has probability 0.12 < 0.3")
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
    assert np.asarray(got_path).dtype.kind == "i", "the path must hold integer state indices"
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
assert np.allclose(np.sum(out_m, axis=1), 1.0), "every final q must be a distribution"
one = run_minibatch(ps_m[:, :1], Wm)
assert np.allclose(one, vagn.transition_matrix(ps_m[:, 0], Wm).mean(axis=-1)), (
    "after one step from the uniform q, q_1 = T(p_1) (1/N, ..., 1/N) = the row means of T")
assert np.allclose(run_minibatch(ps_m[::-1], Wm), out_m[::-1]), (
    "reversing the samples must reverse the results: each sample starts from its own "
    "uniform q and nothing carries over from the sample before")
### BEGIN HIDDEN TESTS
for b in range(6):
    q_ref = np.full(3, 1.0 / 3)
    for t in range(5):
        q_ref = vagn.transition_matrix(ps_m[b, t], Wm) @ q_ref
    assert np.allclose(out_m[b], q_ref), (
        f"sample {b}: expected {q_ref} (eq. 9 five times from the uniform q); got {out_m[b]}")
    assert np.allclose(run_minibatch(ps_m[b:b + 1], Wm)[0], q_ref), (
        f"sample {b} alone must give the same q as inside the minibatch")
from minimanc import engine  # noqa: E402

eng_m = engine("numpy")
g_m = eng_m.grad(lambda W: eng_m.xp.sum(run_minibatch(ps_m, W, xp=eng_m.xp)[:, 0]))(Wm)
E_m = np.zeros_like(Wm)
E_m[1, 0, 2] = 1e-6
fd = (run_minibatch(ps_m, Wm + E_m)[:, 0].sum() - run_minibatch(ps_m, Wm - E_m)[:, 0].sum()) / 2e-6
assert np.shape(g_m) == Wm.shape and np.isclose(g_m[1, 0, 2], fd, rtol=1e-5, atol=1e-9), (
    "run_minibatch must be differentiable with engine('numpy'): use xp operations only")
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 5.6 — learning W with `grad` from a sequence of q-targets
# A teacher automaton `W_true` produced the q-distributions `targets`
# (shape `(T + 1, B, N)`, `targets[0]` is each sample's start) from the
# predicate sequences `ps` (time-major, shape `(T, B, M)`). Recover its
# transitions: starting from `W0`, run `steps` steps of gradient descent
# $W \leftarrow W - \text{lr}\,\nabla L(W)$ on
#
# $$L(W) = \frac{1}{BT}\sum_{t=1}^{T}\sum_{b}
#   \lVert q_t^{(b)}(W) - \text{targets}_t^{(b)} \rVert^2,$$
#
# with the gradient from `engine("numpy")` (our autodiff of chapter 1; write the
# loss against `eng.xp` and use `vagn.rollout(..., xp=eng.xp)`). Return
# `(W, losses)`: the final weights and the list of the `steps` loss values
# (the loss before each update).

# %% solution id=ex05_6 title="Learn W from q-targets with grad"
from minimanc import engine  # noqa: E402


def fit_W(ps, targets, W0, steps=300, lr=20.0):
    ### BEGIN SOLUTION
    eng = engine("numpy")

    def loss(W):
        qs = vagn.rollout(targets[0], ps, W, xp=eng.xp)
        return eng.xp.mean(eng.xp.sum((qs[1:] - targets[1:]) ** 2, axis=-1))

    value_and_grad = eng.value_and_grad(loss)
    W, losses = np.array(W0, dtype=float), []
    for _ in range(steps):
        L, g = value_and_grad(W)
        W = W - lr * np.asarray(g)
        losses.append(float(L))
    return W, losses
    ### END SOLUTION

# %%
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

# %% grade id=ex05_6_tests points=4
rng_f = np.random.default_rng(56)
ps_f = sample_predicates(rng_f, 16, 32)
targets_f = vagn.rollout(vagn.random_state(rng_f, 3, size=32), ps_f, W_true)
W0_f = vagn.init_vagn(rng_f, 3, 3, scale=0.1, mean=0.5)
W0_copy = W0_f.copy()
W_f, losses_f = fit_W(ps_f, targets_f, W0_f, steps=300, lr=20.0)
assert len(losses_f) == 300, f"expected one loss per step (300); got {len(losses_f)}"
assert np.shape(W_f) == (3, 3, 3), f"W must keep the shape (M, N, N) = (3, 3, 3); got {np.shape(W_f)}"  # noqa: E501
assert losses_f[0] > 0.05, f"the loss starts at about 0.29 from W0; got {losses_f[0]:.4f}"
assert losses_f[-1] < 2e-3 and losses_f[-1] < 0.01 * losses_f[0], (
    f"300 steps of lr 20 bring the loss below 2e-3 and 1% of its start ({losses_f[0]:.4f}); "
    f"got {losses_f[-1]:.2e}")
### BEGIN HIDDEN TESTS
assert np.array_equal(W0_f, W0_copy), "fit_W must not modify W0 in place"
qs_f = vagn.rollout(targets_f[0], ps_f, W_f)
final = np.mean(np.sum((qs_f[1:] - targets_f[1:]) ** 2, axis=-1))
assert final <= losses_f[-1] + 1e-6, (
    f"the returned W must be the trained one: its loss {final:.2e} should not exceed the "
    f"last recorded loss {losses_f[-1]:.2e}")
for name, p in zip(["road clear", "lead close", "crossing"], np.eye(3)):
    err = np.abs(vagn.transition_matrix(p, W_f) - vagn.transition_matrix(p, W_true)).max()
    assert err < 0.15, f"only {name!r}: the learned T differs from the teacher's by {err:.3f}"
ps_h = sample_predicates(rng_f, 16, 32)
q0_h = vagn.random_state(rng_f, 3, size=32)
held = np.mean(np.sum((vagn.rollout(q0_h, ps_h, W_f)[1:] - vagn.rollout(q0_h, ps_h, W_true)[1:])
                      ** 2, axis=-1))
assert held < 5e-3, f"held-out loss should be below 5e-3; got {held:.2e}"
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
