# %% [markdown]
# # Chapter 5 — vAGN: the behaviour planner as a soft automaton
#
# Module built in this chapter: `minimanc.vagn` (paper section IV-B, eqs. 8–9).
#
# A classical behaviour planner is a finite automaton: *cruise*, *follow the
# car ahead*, *yield to crossing traffic*, with transitions triggered by
# facts about the scene ("a lead vehicle is close"). MANC keeps this structure
# but makes it differentiable, so it can be learned from human driving:
#
# * the state is a **distribution** $q_t \in \mathbb{R}^N$ over $N$ q-states
#   (like the hidden state of an LSTM, but every entry is a probability);
# * the facts are the **visual predicates** $p \in \mathbb{R}^M$ from the CNN of
#   chapter 6 (eq. 7);
# * each predicate $i$ owns a weight matrix $W_i \in \mathbb{R}^{N\times N}$ and the
#   transition matrix is generated from the predicates:
#
# $$W^{p} = \sum_{i} p_i W_i \quad\text{(eq. 8)},\qquad
#   q_t = \underset{\text{along column}}{\mathrm{softmax}}\big(\mathrm{ReLU}(W^{p})\big)\, q_{t-1}
#   \quad\text{(eq. 9)}.$$
#
# **Convention.** $T_{ij} = P(q_t = i \mid q_{t-1} = j)$: column $j$ holds the
# transitions *out of* state $j$, so every column sums to one and a step is the
# matrix–vector product $q_t = T q_{t-1}$.
#
# **Objectives.** After this chapter you can
# - build the vAGN transition matrix from predicates (eqs. 8–9) and step the soft automaton
# - train it by gradient descent and read its q-states
#
# **Prerequisites.** Chapter 2 (softmax, training); Markov chains and column-stochastic
# matrices.
#
# **Time.** About 60 minutes for the tutorial and 120 for the exercises.

# %%
import matplotlib.pyplot as plt
import numpy as np

from minimanc import engine, vagn
from minimanc.viz.automaton import plot_automaton, plot_q_heatmap

np.set_printoptions(precision=3, suppress=True)
rng = np.random.default_rng(0)

# %% [markdown]
# ## 1. A hand-built automaton: cruise, follow, yield
# Three q-states and three predicates, all in $[0, 1]$:
#
# | predicate | meaning | what its $W_i$ does |
# |---|---|---|
# | $p_0$ | road clear | +3 on the *cruise* row: every state moves to cruise |
# | $p_1$ | lead vehicle close | +3 on the *follow* row |
# | $p_2$ | crossing traffic | +4 on the *yield* row, −3 on the *cruise* row |
#
# Each $W_i$ also gets +1 on the diagonal: a little stickiness, so that the
# planner does not flicker. Rows are "to", columns are "from".

# %%
STATES = ["cruise", "follow", "yield"]
PREDICATES = ["road clear", "lead close", "crossing"]
CRUISE, FOLLOW, YIELD = 0, 1, 2

W_hand = np.zeros((3, 3, 3))
W_hand[0, CRUISE, :] = 3.0
W_hand[1, FOLLOW, :] = 3.0
W_hand[2, YIELD, :] = 4.0
W_hand[2, CRUISE, :] = -3.0
W_hand += np.eye(3)[None]

for p in ([1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1]):
    T = vagn.transition_matrix(np.array(p, float), W_hand)
    assert np.allclose(T.sum(axis=0), 1.0)
    print(f"p = {p}\n{T}\n")
to_cruise = vagn.transition_matrix(np.array([1.0, 0.0, 0.0]), W_hand)[CRUISE]
print(f"road clear: each column sends {to_cruise.min():.2f} to {to_cruise.max():.2f} of its "
      f"mass to cruise")

# %% [markdown]
# With only *road clear* ($p = [1, 0, 0]$) every column sends most of its mass to
# *cruise* (the last line above). With road clear **and** crossing traffic, the −3 of the
# crossing predicate cancels the +3 of road clear on the cruise row: predicates
# interact through the sum of eq. 8, not one at a time.
#
# `plot_automaton` draws the graph: nodes are q-states, arrow $j \to i$ has a
# width proportional to $T_{ij}$, rings are self-loops.

# %%
fig, axes = plt.subplots(1, 3, figsize=(12, 4))
for ax, p, title in zip(axes, ([1, 0, 0], [0, 1, 0], [0, 0, 1]), PREDICATES):
    T = vagn.transition_matrix(np.array(p, float), W_hand)
    plot_automaton(T, ax=ax, labels=STATES)
    ax.set_title(f"only '{title}'")
plt.show()

# %% [markdown]
# ## 2. Driving the automaton with hand-set predicates
# A 30-step drive: the road is clear, a slower car appears ahead (the *lead
# close* predicate ramps up), it turns off, a crossing car appears, and the
# road is clear again. We start from Algorithm 1's uniform $q'$.

# %%
T_steps = 30
ps = np.zeros((T_steps, 3))
ps[:, 0] = 1.0                                   # road clear ...
ps[8:18, 1] = np.minimum(1.0, np.arange(1, 11) / 4)  # ... a lead vehicle approaches
ps[8:18, 0] = 1.0 - ps[8:18, 1]
ps[20:25, 2] = 1.0                               # crossing traffic
ps[20:25, 0] = 0.0

qs = vagn.rollout(vagn.uniform_state(3), ps, W_hand)
print("shape of qs:", qs.shape, "(T + 1, N): qs[0] is q'")
assert np.allclose(qs.sum(axis=1), 1.0) and np.all(qs >= 0)

fig, axes = plt.subplots(2, 1, figsize=(9, 4.2), sharex=True)
axes[0].imshow(ps.T, aspect="auto", cmap="Greys", vmin=0, vmax=1, interpolation="nearest",
               extent=(0.5, T_steps + 0.5, 2.5, -0.5))
axes[0].set_yticks(range(3))
axes[0].set_yticklabels(PREDICATES)
axes[0].set_title("predicates $p_t$")
plot_q_heatmap(qs, ax=axes[1], labels=STATES, colorbar=False)
axes[1].set_title("q-distribution $q_t$ (darker = more probable)")
plt.tight_layout()
plt.show()

# %% [markdown]
# The most probable q-state at each step, and the single most probable *path*
# (Viterbi over the time-varying transition matrices). They agree here; in
# general the per-step argmax of marginals need not be a likely path.

# %%
ml = vagn.most_likely_states(qs)
Ts = vagn.transition_matrix(ps, W_hand)          # (T, N, N): one matrix per step
path, logp = vagn.most_likely_path(vagn.uniform_state(3), Ts)
print("argmax :", "".join("CFY"[s] for s in ml))
print("viterbi:", "".join("CFY"[s] for s in path), f"(log-probability {logp:.2f})")
assert ml[5] == CRUISE and ml[15] == FOLLOW and ml[23] == YIELD and ml[29] == CRUISE

# %% [markdown]
# ## 3. ReLU does not make zeros: every transition stays possible
# ReLU "preserves only the positive transitions" (section IV-B) — but the
# softmax that follows turns a zero into $e^0 = 1$, exactly like any other
# logit. A column whose logits after ReLU are $R_{\cdot j}$ gives
#
# $$T_{ij} = \frac{e^{R_{ij}}}{\sum_r e^{R_{rj}}}
#   \;\ge\; \frac{1}{1 + (N-1)\,e^{\max_r R_{rj}}} > 0 .$$
#
# So the automaton graph is **always complete**. With all predicates off
# ($p = 0$) every column is uniform, and the *yield → cruise* transition under
# crossing traffic, which the −3 was meant to forbid, is merely small.

# %%
T0 = vagn.transition_matrix(np.zeros(3), W_hand)
print("p = 0 gives a uniform T:\n", T0)
T_cross = vagn.transition_matrix(np.array([0.0, 0.0, 1.0]), W_hand)
print(f"P(yield -> cruise | crossing) = {T_cross[CRUISE, YIELD]:.4f}")
print(f"smallest entry of T(crossing)  = {vagn.min_transition_probability([0, 0, 1], W_hand):.4f}")
R = np.maximum(vagn.combined_weights(np.array([0.0, 0.0, 1.0]), W_hand), 0)
bound = 1 / (1 + 2 * np.exp(R.max(axis=0)))
assert np.all(T_cross >= bound[None, :] - 1e-15) and np.all(T_cross > 0)

# %% [markdown]
# What this means for reading a learned vAGN:
#
# * **No edge can be removed.** "Impossible" transitions only exist after you
#   pick a threshold, e.g. `plot_automaton(..., min_prob=0.05)`. Report the
#   threshold with the figure.
# * **A negative weight and a zero weight look the same.** Once $W^p_{ij} \le 0$
#   the ReLU outputs 0 whatever the value, and no gradient flows through that
#   entry (it is "dead" for this input). To make a transition *unlikely* the
#   model must make the *other* entries of the column large.
# * **Confidence is bounded by the weight scale.** A transition probability of
#   0.99 needs a logit gap of $\log(0.99 (N-1)/0.01) \approx 5.3$ for $N = 3$.

# %%
fig, axes = plt.subplots(1, 2, figsize=(8, 4))
plot_automaton(T_cross, ax=axes[0], labels=STATES)
axes[0].set_title("crossing: all edges")
plot_automaton(T_cross, ax=axes[1], labels=STATES, min_prob=0.05)
axes[1].set_title("crossing: edges with P ≥ 0.05")
plt.show()

# %% [markdown]
# ## 4. Where the automaton settles: the stationary distribution
# While the predicates stay constant, $T$ is constant and $q_t = T^t q_0$. All
# entries of $T$ are positive, so by Perron–Frobenius there is one stationary
# distribution $\pi = T\pi$, and $T^t q_0 \to \pi$ from any start. It answers
# "if the scene stays like this, which behaviour does the planner end up in?"

# %%
for name, p in zip(PREDICATES, np.eye(3)):
    T = vagn.transition_matrix(p, W_hand)
    pi = vagn.stationary_distribution(T)
    assert np.allclose(T @ pi, pi)
    q = vagn.random_state(rng, 3)
    for _ in range(50):
        q = T @ q
    assert np.allclose(q, pi, atol=1e-8)
    print(f"only {name!r:13}: pi = {np.round(pi, 3)}")

# %% [markdown]
# ## 5. Learning $W$ from sequences with `grad`
# We never know the true q-states of a human driver, but here we do: the
# hand-built automaton is the teacher. We sample random predicate sequences
# (piecewise constant, like scenes that change every few steps) and random
# start distributions ($q'$ of Algorithm 1), roll the teacher out, and fit a
# fresh $W$ so that the rolled-out distributions match:
#
# $$L(W) = \frac{1}{B T}\sum_{b,t} \lVert q_t^{(b)}(W) - q_t^{(b),\text{teacher}} \rVert^2 .$$
#
# The loss is written once against `xp`; `engine("numpy")` (our autodiff of
# chapter 1) computes the gradient. We start from small *positive* weights
# (`mean=0.5`): the predicates are non-negative, so every entry of $W^p$
# begins outside ReLU's dead zone and receives gradient.

# %% tags=["nbval-ignore-output"]
def sample_predicates(rng, T, B, M=3):
    """Piecewise-constant random predicate sequences, shape (T, B, M)."""
    ps = np.zeros((T, B, M))
    for b in range(B):
        t = 0
        while t < T:
            d = rng.integers(3, 8)
            ps[t:t + d, b] = rng.random(M) * (rng.random(M) < 0.6)
            t += d
    return ps


def loss(W, ps, q0, target, xp):
    qs = vagn.rollout(q0, ps, W, xp=xp)
    return xp.mean(xp.sum((qs[1:] - target[1:]) ** 2, axis=-1))


ps_train = sample_predicates(rng, 20, 64)
q0_train = vagn.random_state(rng, 3, size=64)
target_train = vagn.rollout(q0_train, ps_train, W_hand)

eng = engine("numpy")
value_and_grad = eng.value_and_grad(loss)
W = vagn.init_vagn(rng, 3, 3, scale=0.1, mean=0.5)
history = []
for _ in range(300):
    L, g = value_and_grad(W, ps_train, q0_train, target_train, eng.xp)
    W = W - 20.0 * g
    history.append(float(L))
print(f"training loss: {history[0]:.4f} -> {history[-1]:.6f}")
assert history[-1] < 0.01 * history[0]

# %% [markdown]
# Held-out sequences, and the learned transition matrices next to the
# teacher's. Compare $T$, not $W$: many $W$ give the same $T$ (any negative
# value is "zero" after ReLU), so the weights themselves are not identifiable.

# %% tags=["nbval-ignore-output"]
ps_val = sample_predicates(rng, 20, 64)
q0_val = vagn.random_state(rng, 3, size=64)
val = loss(W, ps_val, q0_val, vagn.rollout(q0_val, ps_val, W_hand), np)
print(f"held-out loss: {val:.6f}")
assert val < 0.002
for name, p in zip(PREDICATES, np.eye(3)):
    err = np.abs(vagn.transition_matrix(p, W) - vagn.transition_matrix(p, W_hand)).max()
    print(f"only {name!r:13}: max |T_learned - T_teacher| = {err:.3f}")
    assert err < 0.1

fig, axes = plt.subplots(1, 3, figsize=(13, 3.6))
axes[0].semilogy(history)
axes[0].set_xlabel("gradient step")
axes[0].set_title("training loss")
plot_automaton(vagn.transition_matrix(np.array([0, 1.0, 0]), W_hand), ax=axes[1],
               labels=STATES)
axes[1].set_title("teacher, 'lead close'")
plot_automaton(vagn.transition_matrix(np.array([0, 1.0, 0]), W), ax=axes[2], labels=STATES)
axes[2].set_title("learned, 'lead close'")
plt.show()

# %% [markdown]
# ## 6. Same code, other engine
# The loss above never mentions NumPy or JAX: flip the engine and the gradient
# agrees to rounding error.

# %%
jx = engine("jax")
batch = (ps_val[:, :8], q0_val[:8], vagn.rollout(q0_val[:8], ps_val[:, :8], W_hand))
g_np = eng.grad(loss)(W_hand + 0.3, *batch, eng.xp)
g_jax = jx.grad(loss)(W_hand + 0.3, *batch, jx.xp)
diff = np.abs(np.asarray(g_jax) - g_np).max()
print(f"max |grad_numpy - grad_jax| < 1e-10: {diff < 1e-10}")
assert diff < 1e-10

# %% [markdown]
# ## 7. Algorithm 1: a fresh $q'$ for every sample
# The paper never knows the true q-state of the human driver. Algorithm 1
# therefore starts vAGN from $q' = \texttt{UniformInit}()$ (or
# $\texttt{RandomInit}()$) **for every sample of every minibatch**: no sample
# inherits another's q. With a single step, as Algorithm 1 is written, the q
# that reaches the DMP is $T(p)\,\tfrac1N\mathbf 1$ — the row means of $T$, a
# function of this one image with no memory at all. Run over a window of $k$
# steps instead, the start is forgotten geometrically: below, the largest
# distance between the q reached from the uniform start and from each one-hot
# start, on the drive of section 2.

# %%
q_unif = vagn.rollout(vagn.uniform_state(3), ps, W_hand)
T1 = vagn.transition_matrix(ps[0], W_hand)
assert np.allclose(q_unif[1], T1.mean(axis=1))    # one step from uniform = row means of T
print("one step from the uniform q' = the row means of T(p_1):", np.round(q_unif[1], 3))
gaps = np.max([np.abs(vagn.rollout(q0, ps, W_hand) - q_unif).max(axis=1) for q0 in np.eye(3)],
              axis=0)
for k in (0, 1, 2, 4, 8):
    print(f"after {k} steps: max |q(one-hot start) - q(uniform start)| = {gaps[k]:.0e}")
assert gaps[0] > 0.6 and gaps[8] < 1e-3 and np.all(np.diff(gaps) <= 1e-12)

# %% [markdown]
# The course's training (chapters 8–9) resets $q'$ at the start of each
# *window* of consecutive steps (a whole 20-s scene for MANC), so the
# automaton's memory is exercised; `TrainConfig(q_seq_len=1)` is Algorithm 1's
# single step for the vAGN-only model.
#
# ## Summary
# * `transition_matrix(p, W)` is eqs. 8–9: a predicate-weighted sum of
#   matrices, a ReLU and a column softmax; `step` and `rollout` apply it.
# * Every column is a distribution, so $q$ stays a distribution forever; no
#   transition is ever exactly impossible ($e^0 = 1$).
# * `stationary_distribution`, `most_likely_states`, `most_likely_path`,
#   `plot_automaton` and `plot_q_heatmap` are the tools to read a learned
#   planner. Chapter 6 builds the predicates $p$ from images and asks *where*
#   in the image each q-state looks.
# * Algorithm 1 starts every sample from a fresh $q'$; over a window the start
#   is forgotten within a few steps.

# %% [markdown]
# ## Paper vs. this course
# Where this chapter departs from section IV-B and Algorithm 1 of the paper,
# and where the paper itself slips:
#
# * **Eq. 8's index set.** The sum is written over $i \in \{0, M-1\}$, a set of
#   two elements; it means all $M$ predicates, $i = 0, \dots, M-1$. Likewise
#   "$W_i \in \mathcal W \in \mathbb R^{N\times N}$": $\mathcal W$ is
#   $\mathbb R^{M\times N\times N}$ and each $W_i$ is $N \times N$.
# * **"ReLU preserves only the positive transitions."** It does not remove any:
#   the column softmax that follows turns a ReLU zero into $e^0 = 1$, so every
#   transition keeps a probability $\ge 1/(1 + (N-1)e^{\max R})$ (section 3).
#   We read sparse automata off only with a stated threshold (`min_prob`).
# * **"Softmax ... ensures that the columns of $\mathcal W^{p^v}$ sum to one"**:
#   it is the softmax's *output* $T$ whose columns sum to one, and the "dot
#   product" of eq. 9 is the matrix–vector product $q_t = T q_{t-1}$. We fix
#   the convention $T_{ij} = P(q_t = i \mid q_{t-1} = j)$ and renormalise $q$
#   after each step (the identity in exact arithmetic; it stops float32 drift).
# * **Predicates pass through a sigmoid after eq. 7.** Eq. 7 ends in a linear
#   layer, so $p^v$ is unbounded and may be negative. The course's models
#   (chapter 8, `ModelConfig.predicate_activation="sigmoid"`; `"linear"` is
#   eq. 7 as written) squash $p$ into $(0, 1)$, like the hand-set predicates
#   here: with linear predicates training let $|p|$ grow until the softmax
#   saturated and q stopped depending on the image.
# * **Algorithm 1 runs vAGN for one step from $q'$**; with a uniform $q'$ that
#   step gives the row means of $T$ and no memory (section 7). Our DMP models
#   train on windows spanning whole scenes, resetting $q'$ once per window,
#   and the vAGN-only baseline keeps Algorithm 1's single step
#   (`q_seq_len=1`).
# * **Learning from q-targets (section 5) is a teaching device.**
#   The paper never observes q; it trains vAGN only through the DMP's action
#   loss. With known q-targets we can check that `grad` recovers the
#   teacher's transition matrices (not its weights: $W$ is not identifiable
#   through the ReLU). Exercises 5.6 and 5.7 train from the action alone, as
#   the paper does, and test when q then recovers the teacher's states.
# * **Algorithm 1's update** is $\theta \leftarrow \theta - \gamma\frac1m\nabla L$
#   with $L$ already a mean (MSE) over the minibatch; the extra $\frac1m$ only
#   rescales the learning rate $\gamma$. We average once.
# * **Reading the automaton.** The stationary distribution and Viterbi paths
#   are our additions; the paper reads the automaton from heat maps of $q_t$
#   and from saliency maps (chapter 6).
