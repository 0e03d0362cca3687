# %% [markdown]
# # Chapter 11 — Graded exercises: the DAgger schedule, the mixture, aggregation, the budget
#
# Module built in this chapter: `minimanc.dagger` (with `minimanc.world` for the data).
#
# DAgger (Ross, Gordon & Bagnell 2011) trains round after round: drive with a mixture
# of the expert and the current policy, label every visited state with the expert's
# controls, **aggregate** the labelled states with all earlier data, retrain. Two
# exercises, each checked by the grade cell below it:
#
# 1. **The β schedule and the mixture**: how much the expert drives in round $i$.
# 2. **Aggregation and the label budget**: the data a round trains on, and how a
#    fixed number of expert labels is shared between the rounds.
#
# Replace each `raise NotImplementedError(...)` with your code.

# %%
import numpy as np

from minimanc import dagger, world

ds = world.generate(5, seed=0, raster=world.RasterConfig(size=16), workers=1)
print(ds)

# %% [markdown]
# ## Exercise 11.1 — the β schedule and the mixture
# Round 0 is behaviour cloning: the data are the expert's own demonstrations, as if the
# expert had driven with weight $\beta_0 = 1$. In round $i \ge 1$ the mixture
# $\pi_i = \beta_i\,\pi^* + (1 - \beta_i)\,\hat\pi_{i-1}$ drives: at every step and in
# every scene the expert's control is applied with probability $\beta_i$, the policy's
# otherwise. The schedule is geometric, $\beta_i = p^i$.
#
# * `beta_schedule(p, rounds)` returns the list $[\beta_0, \beta_1, \dots, \beta_{rounds}]$
#   (floats; $\beta_0 = 1$ whatever $p$, also for $p = 0$).
# * `mix(expert, policy, beta, u)`: `expert` and `policy` are `(B, 2)` controls, `u` a
#   `(B,)` array of uniform draws in $[0, 1)$; row `b` of the result is `expert[b]` where
#   `u[b] < beta`, else `policy[b]`.

# %% solution id=ex11_1 title="The beta schedule and the mixture" forbids="minimanc.dagger.beta_schedule,minimanc.dagger.mix"  # noqa: E501
def beta_schedule(p, rounds):
    ### BEGIN SOLUTION
    return [1.0] + [float(p) ** i for i in range(1, rounds + 1)]
    ### END SOLUTION


def mix(expert, policy, beta, u):
    ### BEGIN SOLUTION
    return np.where((np.asarray(u) < beta)[:, None], expert, policy)
    ### END SOLUTION

# %% grade id=ex11_1_tests points=3
assert beta_schedule(0.5, 3) == [1.0, 0.5, 0.25, 0.125], "p = 0.5: 1, 0.5, 0.25, 0.125"
assert beta_schedule(0.0, 2) == [1.0, 0.0, 0.0], "round 0 is BC (beta 1) even for p = 0"
e = np.array([[1.0, 0.1], [2.0, 0.2], [3.0, 0.3]])
p = np.array([[-1.0, -0.1], [-2.0, -0.2], [-3.0, -0.3]])
out = mix(e, p, 0.5, np.array([0.1, 0.9, 0.5]))
assert np.array_equal(out, [[1.0, 0.1], [-2.0, -0.2], [-3.0, -0.3]]), (
    "the expert where u < beta (row 0 only: u = 0.5 is not below 0.5)")
### BEGIN HIDDEN TESTS
b = beta_schedule(0.8, 4)
assert len(b) == 5 and np.allclose(b, [1.0, 0.8, 0.64, 0.512, 0.4096]), b
assert beta_schedule(1.0, 3) == [1.0, 1.0, 1.0, 1.0], "p = 1: the expert always drives"
assert len(beta_schedule(0.3, 1)) == 2, "rounds = 1: beta_0 and beta_1"
assert np.array_equal(mix(e, p, 1.0, np.array([0.0, 0.5, 0.999])), e), "beta = 1: the expert"
assert np.array_equal(mix(e, p, 0.0, np.array([0.0, 0.5, 0.999])), p), "beta = 0: the policy"
assert np.array_equal(mix(e, p, 0.25, np.array([0.2, 0.3, 0.0])),
                      [[1.0, 0.1], [-2.0, -0.2], [3.0, 0.3]]), "rows 0 and 2 are below 0.25"
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 11.2 — aggregation and the label budget
# **Aggregation.** The data of round $i$ are the scenes of every earlier round, one
# after the other. Write `aggregate(datasets)` for a list of `world.Dataset`s: each of
# the arrays named in `world.fileformat.ARRAY_FIELDS` (`bev`, `ego`, `controls`, ...)
# concatenated along the scene axis, the per-scene metadata lists of
# `world.fileformat.PER_SCENE_KEYS` concatenated likewise (the other metadata: the first
# dataset's), and the maps one after the other; return
# `world.Dataset(**arrays, maps=maps, meta=meta)`.
#
# **Budget.** BC and DAgger are compared at the same number of expert-labelled samples:
# every labelled state counts, the demonstrations included, and a scene of `steps`
# states costs `steps` labels. Write `split_budget(total, steps, rounds)` that returns
# `(initial, per_round)`: with $n = \lfloor total / steps \rfloor$ scenes in all, each of
# the `rounds` DAgger rounds gets $\lfloor n / (rounds + 1) \rfloor$ scenes and round 0
# the rest; raise a `ValueError` when a round would get no scene.

# %% solution id=ex11_2 title="Aggregation and the label budget" forbids="minimanc.dagger.concat,minimanc.dagger.plan_budget"  # noqa: E501
def aggregate(datasets):
    ### BEGIN SOLUTION
    arrays = {f: np.concatenate([getattr(d, f) for d in datasets])
              for f in world.fileformat.ARRAY_FIELDS}
    meta = dict(datasets[0].meta)
    for key in world.fileformat.PER_SCENE_KEYS:
        meta[key] = [x for d in datasets for x in d.meta[key]]
    maps = [m for d in datasets for m in d.maps]
    return world.Dataset(**arrays, maps=maps, meta=meta)
    ### END SOLUTION


def split_budget(total, steps, rounds):
    ### BEGIN SOLUTION
    n = total // steps
    share = n // (rounds + 1)
    if share < 1:
        raise ValueError(f"budget too small: {n} scenes for {rounds + 1} rounds")
    return n - share * rounds, [share] * rounds
    ### END SOLUTION

# %% grade id=ex11_2_tests points=3
a, b = ds.subset([0, 1]), ds.subset([4])
agg = aggregate([a, b])
assert len(agg) == 3, "2 + 1 scenes"
assert agg.bev.shape == (3, 40, 16, 16, 3), f"scenes stacked along axis 0, got {agg.bev.shape}"
assert np.array_equal(agg.controls[2], ds.controls[4]), "the last scene is ds's scene 4"
assert len(agg.meta["tags"]) == 3 and len(agg.meta["recipes"]) == 3, "one tag per scene"
assert split_budget(400, 40, 3) == (4, [2, 2, 2]), "10 scenes: 4 demonstrations, then 2 per round"
### BEGIN HIDDEN TESTS
agg3 = aggregate([ds.subset([3]), ds.subset([0, 1, 2]), ds.subset([3, 4])])
assert len(agg3) == 6 and agg3.ego.shape == (6, 40, 3)
assert np.array_equal(agg3.ado_valid[1:4], ds.ado_valid[:3]), "order kept: scene 3, 0, 1, 2, ..."
assert agg3.meta["scene_index"] == [3, 0, 1, 2, 3, 4], agg3.meta["scene_index"]
assert agg3.meta["seed"] == 0 and agg3.meta["raster"] == ds.meta["raster"]
assert agg3.maps[4] is ds.maps[3] or agg3.maps[4].recipe == ds.maps[3].recipe
assert np.array_equal(agg3.goal_bev[5], ds.goal_bev[4])
assert split_budget(450, 40, 2) == (5, [3, 3]), "11 scenes: 3 per round, the remainder to round 0"
assert split_budget(80, 40, 1) == (1, [1]), "2 scenes: one demonstration, one driven"
assert split_budget(39 * 40 + 39, 40, 5) == (9, [6] * 5), "39 whole scenes"
try:
    split_budget(100, 40, 3)
except ValueError:
    pass
else:
    raise AssertionError("2 scenes cannot feed 4 rounds: a ValueError")
### END HIDDEN TESTS

# %% [markdown]
# ## The library's versions at work
# `minimanc.dagger` has both (`dagger.beta_schedule`, `dagger.mix`, `dagger.concat`,
# `dagger.plan_budget`). Here the world's human driver drives its own scenes (β = 1),
# every visited state labelled by asking it what it would do there; those labels are the
# logged controls, and one scene is `steps` labelled samples against the budget.

# %%
teacher = dagger.WorldTeacher(ds, agents="reactive")
col = dagger.collect(None, teacher, [0, 1], beta=1.0)
print(f"{col.labelled} labelled samples, {len(col.data)} scenes kept, "
      f"expert share {col.expert_share:.2f}")
deviation = float(np.abs(col.data.controls - ds.controls[[0, 1]]).max())
print(f"labels equal the log to 1e-4: {deviation < 1e-4}")
plan = dagger.plan_budget(400, 40, 3)
print(f"budget 400: {plan.initial} demonstrations + {list(plan.per_round)} driven scenes, "
      f"{plan.used} labels")
assert deviation < 1e-4 and col.labelled == 80 and plan.used == 400
