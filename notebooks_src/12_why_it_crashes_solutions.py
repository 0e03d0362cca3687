# %% [markdown]
# # Chapter 12 — Graded exercises: the bounds, the expert's perception, the ablation, the fix
#
# Modules built in this chapter: `minimanc.diagnose` and `minimanc.viz.investigation` (its
# figures); the exercises use `minimanc.diagnose.bounds`, `minimanc.diagnose.privileged`,
# `minimanc.diagnose.perception_targets`, `minimanc.diagnose.probe` and
# `minimanc.world.history`.
# Read the tutorial `tutorials/12_why_it_crashes.ipynb` first. Replace each
# `raise NotImplementedError(...)` with your code and run the grade cell below it;
# `minimanc grade exercises/12_why_it_crashes.ipynb` scores the notebook.
#
# 1. **The style floor, field by field**: the track errors, and which part of the hidden
#    style the floor's error comes from.
# 2. **What the expert perceives and what it demands**: the braking a leader asks for, the
#    lane seen from the ego.
# 3. **Two ways to ask which input matters**: the ablation table, and shuffling an input
#    instead of removing it.
# 4. **Faded history at another decay**: the past boxes a raster draws.
# 5. **An open experiment**: a small input set, and a written answer.
# 6. **A masked loss and its gradient**: every target weighed alike, derived by hand.
# 7. **The history planes, from the poses**: the learner's raster's past boxes.
# 8. **How far ahead must the raster reach?** A view designed from the data, and a written
#    answer.
# 9. **A probe with more features than states**: the ridge probe solved in the states'
#    dimension, derived; what the raster's pixels hold linearly, and a written answer.

# %%
import dataclasses
import math

import matplotlib.pyplot as plt
import numpy as np

from minimanc import diagnose, world
from minimanc.dagger.expert import HumanExpert
from minimanc.diagnose import bounds
from minimanc.diagnose import privileged as P
from minimanc.metrics.trajectory import along_cross_track
from minimanc.viz.investigation import plot_investigation_attempts
from minimanc.world.driver import HumanStyle, random_style

data = world.generate(28, seed=1, raster=world.RasterConfig(size=16), workers=1)
train, val = data.split(22)
X, Y = P.demonstrations(train)
Xv, Yv = P.demonstrations(val)
expert = HumanExpert(train)
print(f"{len(train)} training scenes ({X.shape[0]} states), {len(val)} validation scenes "
      f"({Xv.shape[0]} states), {len(P.FEATURES)} features")

# %% [markdown]
# ## Exercise 12.1 — the style floor, field by field
# The style floor (tutorial section 2) re-drives a scene with the population's median style
# and measures how far that driver ends up from the logged human. Which part of the hidden
# style is the error made of?
#
# * `track_errors(ego, human)`: for driven poses `ego (S, T, 3)` and the human's
#   `human (S, T, 3)` (`[x, y, yaw]`), return three arrays of shape `(S,)`, each a mean over
#   the steps: the ADE (the mean distance between the two positions), the mean absolute
#   part of the displacement *along* the human's heading at that step, and the mean
#   absolute part *across* it. The driven yaw does not enter.
# * `field_floor(ds, scenes, styles, field)`: re-drive each scene `s` of `scenes` of `ds`
#   (`bounds.floor_rollout`) with the field-wise median of the list `styles` (a `float` per
#   field; for an even number of styles the mean of the two middle values), except that
#   the field named `field` takes the scene's own value, `ds.tags[s]["style"][field]`
#   (`field=None`: no exception, the plain floor). Return a dict with the means over those
#   scenes of your three errors, `{"ade": ..., "along": ..., "cross": ...}` (floats).
#
# `field_floor(val, range(6), styles, "v0")` next to `field_floor(val, range(6), styles,
# None)` says how much of the floor the desired speed alone explains. `bounds.median_style`,
# `metrics.trajectory.ade` and `metrics.trajectory.along_cross_track` are switched off
# while this exercise is graded.
#
# <details><summary>Hint 1 (the idea)</summary>
#
# Along and across are the displacement seen in the human's own frame at that step, as
# chapter 7 put points into the ego's frame. A rotation keeps lengths: what must
# $\text{along}^2 + \text{cross}^2$ be at every step?
# </details>
#
# <details><summary>Hint 2 (the method)</summary>
#
# The styles are dataclasses: `dataclasses.fields`, `dataclasses.replace` and
# `HumanStyle(**...)` build one from another. Each scene needs its own style, so its own
# re-drive. Check the whole with a population of one: a scene's own style re-drives its
# log, so its floor is zero.
# </details>

# %% solution id=ex12_1 title="The style floor, field by field" forbids="minimanc.diagnose.bounds.median_style,minimanc.metrics.trajectory.ade,minimanc.metrics.trajectory.along_cross_track"  # noqa: E501
def track_errors(ego, human):
    ### BEGIN SOLUTION
    e, h = np.asarray(ego, dtype=float), np.asarray(human, dtype=float)
    d = e[..., :2] - h[..., :2]
    c, s = np.cos(h[..., 2]), np.sin(h[..., 2])
    along = d[..., 0] * c + d[..., 1] * s
    cross = -d[..., 0] * s + d[..., 1] * c
    return (np.linalg.norm(d, axis=-1).mean(1), np.abs(along).mean(1), np.abs(cross).mean(1))
    ### END SOLUTION


def field_floor(ds, scenes, styles, field):
    ### BEGIN SOLUTION
    names = [f.name for f in dataclasses.fields(HumanStyle)]
    mid = HumanStyle(**{n: float(np.median([getattr(s, n) for s in styles])) for n in names})
    rows = []
    for s in scenes:
        style = mid if field is None else dataclasses.replace(
            mid, **{field: float(ds.tags[s]["style"][field])})
        traj = bounds.floor_rollout(ds, style, scenes=[s])
        rows.append([float(x[0]) for x in track_errors(traj.ego, np.asarray(ds.ego)[[s]])])
    ade_, along, cross = np.mean(rows, axis=0)
    return {"ade": float(ade_), "along": float(along), "cross": float(cross)}
    ### END SOLUTION

# %% grade id=ex12_1_errors_tests points=2
human1 = np.zeros((1, 3, 3))
human1[0, :, 0] = [0.0, 5.0, 10.0]                      # along x, heading 0
ego1 = human1 + np.array([-2.0, 1.0, 0.7])              # 2 m behind, 1 m to the left
got = track_errors(ego1, human1)
assert len(got) == 3, f"expected (ade, along, cross), got {len(got)} values"
assert np.allclose(got[1], [2.0]) and np.allclose(got[2], [1.0]), (
    f"2 m behind and 1 m left of a human heading along x: expected along 2.0, cross 1.0, got "
    f"along {np.round(got[1], 4).tolist()}, cross {np.round(got[2], 4).tolist()}")
assert np.allclose(got[0], [math.sqrt(5.0)]), (
    f"same case: expected ADE sqrt(5) = 2.2361, got {np.round(got[0], 4).tolist()}")
### BEGIN HIDDEN TESTS
test_rng = np.random.default_rng(1211)  # the tests' own draws, not the notebook's
human2 = test_rng.normal(0, 20, size=(5, 11, 3))
ego2 = human2 + test_rng.normal(0, 3, size=(5, 11, 3))
d2 = ego2[..., :2] - human2[..., :2]
c2, s2 = np.cos(human2[..., 2]), np.sin(human2[..., 2])
want = (np.hypot(d2[..., 0], d2[..., 1]).mean(1), np.abs(d2[..., 0] * c2 + d2[..., 1] * s2).mean(1),
        np.abs(d2[..., 1] * c2 - d2[..., 0] * s2).mean(1))
got = track_errors(ego2, human2)
for name, w, g in zip(("ADE", "along", "cross"), want, got):
    assert np.shape(g) == (5,), (
        f"5 scenes of 11 steps: expected {name} of shape (5,), got {np.shape(g)}")
    assert np.allclose(g, w, rtol=1e-10), (
        f"random poses, {name}: expected {np.round(w, 4).tolist()}, "
        f"got {np.round(g, 4).tolist()}")
spun = ego2.copy()
spun[..., 2] += 1.0
assert np.allclose(track_errors(spun, human2)[1], want[1]), "the driven yaw must not enter"
### END HIDDEN TESTS


# %% grade id=ex12_1_floor_tests points=2
own3 = HumanStyle(**val.tags[3]["style"])
got = field_floor(val, [3], [own3], None)
assert set(got) == {"ade", "along", "cross"}, f"expected keys ade, along, cross; got {set(got)}"
assert got["ade"] < 1e-3, (
    f"validation scene 3, a population of one style, scene 3's own: expected the log "
    f"re-driven (ADE below 0.001 m), got {got['ade']:.4f} m")
pop = [random_style(np.random.default_rng(k)) for k in range(31)]
got = field_floor(val, [3], pop, "v0")
assert max(got["along"], got["cross"]) <= got["ade"] + 1e-9 <= got["along"] + got["cross"] + 2e-9, (
    f"validation scene 3, 31 styles, own v0: the ADE must lie between max(along, cross) and "
    f"along + cross (a triangle at every step); got {got}")
### BEGIN HIDDEN TESTS
names = [f.name for f in dataclasses.fields(HumanStyle)]
mid = HumanStyle(**{n: float(np.median([getattr(s, n) for s in pop])) for n in names})
even = pop[:30]
mid_even = HumanStyle(**{n: float(np.median([getattr(s, n) for s in even])) for n in names})
for scenes, field, styles, middle in (([3], "v0", pop, mid), ([0, 5], "T", pop, mid),
                                      ([1], None, even, mid_even)):
    ade_s, along_s = [], []
    for s in scenes:   # the reference, computed before the call
        style = middle if field is None else dataclasses.replace(
            middle, **{field: float(val.tags[s]["style"][field])})
        ego_s = bounds.floor_rollout(val, style, scenes=[s]).ego[0]
        d = ego_s[:, :2] - np.asarray(val.ego[s], dtype=float)[:, :2]
        h = np.asarray(val.ego[s], dtype=float)[:, 2]
        ade_s.append(np.hypot(d[:, 0], d[:, 1]).mean())
        along_s.append(np.abs(d[:, 0] * np.cos(h) + d[:, 1] * np.sin(h)).mean())
    want, want_along = float(np.mean(ade_s)), float(np.mean(along_s))
    got = field_floor(val, scenes, styles, field)
    case = f"validation scenes {scenes}, {len(styles)} styles, own field {field}"
    assert all(type(got[k]) is float for k in ("ade", "along", "cross")), (
        f"{case}: expected three floats, got {got!r}")
    assert math.isclose(got["ade"], want, rel_tol=1e-9), (
        f"{case}: expected the floor's ADE {want:.4f} m, got {got['ade']!r}")
    assert math.isclose(got["along"], want_along, rel_tol=1e-9), (
        f"{case}: expected the floor's along-track error {want_along:.4f} m, "
        f"got {got['along']!r}")
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 12.2 — what the expert perceives, and what it demands
# `HumanExpert(ds).situation(scene, t, pose, speed)` returns a `Situation` with
# `sit.ego` (the ego `Vehicle`: `.v` its speed, `.s` its arc length on its path),
# `sit.path` (its route: `sit.path.pose(s)` returns `((x, y), heading)` of the point at arc
# length `s`), `sit.pose` (the asked `[x, y, yaw]`) and `sit.perceived`, a dict with the
# leader's `gap` (m) and speed `v_lead` (m/s) (`math.inf` without a leader).
#
# * `braking_needed(gap, v, v_lead, s0=2.0)`: how hard must the ego brake for its leader?
#   Return the constant deceleration $b \ge 0$ (m/s²) that, applied from now until the ego
#   has come down to the leader's speed (the leader holds its speed), keeps the gap at `s0`
#   metres or more: the smallest such $b$. It is 0 when the ego is not closing in (or
#   `gap` is `math.inf`), and `math.inf` when it is closing in with the gap already at most
#   `s0`. The arguments may be floats or arrays that broadcast; return a float or an array.
# * `lane(sit)` returns `[lateral, heading, ahead_5, ahead_10, ahead_20]`: with `(px, py), h`
#   the path's point at the ego's arc length, `lateral` is the ego's offset from it across
#   the path (positive to the path's left), `heading` the ego's yaw minus `h` wrapped to
#   $(-\pi, \pi]$ (`world.geometry.wrap_angle`); `ahead_d` is the *ego-frame* lateral
#   coordinate (positive to the ego's left) of the path's point `d` metres further along.
#
# `P.features` is switched off while this exercise is graded (so are the parts of the
# library that call it).
#
# <details><summary>Hint 1 (the idea)</summary>
#
# Braking: watch the leader from the leader: in its frame the ego comes closer at the
# closing speed and slows down at $b$; how far does it travel before it stops closing in?
# Lane: every number is a coordinate in some frame, the path's frame at the ego (for
# `lateral`) or the ego's frame (for `ahead_d`).
# </details>
#
# <details><summary>Hint 2 (the method)</summary>
#
# Braking: set that distance equal to the room there is, solve for $b$, then treat the
# three special cases with `np.where` (the case that divides by zero must not reach the
# division). Lane: a frame rotated by an angle θ has its left axis along
# $(-\sin\theta, \cos\theta)$; which operation gives a vector's component along an axis?
# </details>

# %% solution id=ex12_2 title="What the expert perceives and demands" forbids="minimanc.diagnose.privileged.features"  # noqa: E501
def braking_needed(gap, v, v_lead, s0=2.0):
    ### BEGIN SOLUTION
    gap, v, v_lead = np.broadcast_arrays(*(np.asarray(a, dtype=float) for a in (gap, v, v_lead)))
    closing = np.maximum(v - v_lead, 0.0)
    room = np.where(np.isfinite(gap) & (gap > s0), gap - s0, 1.0)
    # relative motion: the closing speed w falls to 0 over w^2 / (2 b) metres
    b = np.where(closing > 0, closing**2 / (2.0 * room), 0.0)
    b = np.where(np.isinf(gap), 0.0, np.where((closing > 0) & (gap <= s0), np.inf, b))
    return float(b) if b.ndim == 0 else b
    ### END SOLUTION


def lane(sit):
    ### BEGIN SOLUTION
    x, y, yaw = (float(q) for q in sit.pose)
    (px, py), h = sit.path.pose(float(sit.ego.s))
    out = [-math.sin(h) * (x - px) + math.cos(h) * (y - py),
           float(world.geometry.wrap_angle(yaw - h))]
    for d in P.AHEAD:
        (qx, qy), _ = sit.path.pose(float(sit.ego.s) + d)
        out.append(-math.sin(yaw) * (qx - x) + math.cos(yaw) * (qy - y))
    return np.array(out)
    ### END SOLUTION

# %% grade id=ex12_2_braking_tests points=2
cases = ((22.0, 10.0, 0.0, 2.5, "gap 22 m, 10 m/s behind a standing car"),
         (30.0, 8.0, 10.0, 0.0, "gap 30 m, the leader drives away"),
         (math.inf, 12.0, 0.0, 0.0, "no leader"),
         (1.5, 5.0, 4.0, math.inf, "gap 1.5 m < s0, closing at 1 m/s"))
for gap2, v2, lead2, want2, case2 in cases:
    got2 = float(braking_needed(gap2, v2, lead2))
    assert got2 == want2 or math.isclose(got2, want2, rel_tol=1e-9), (
        f"{case2}: expected b = {want2} m/s², got {got2!r}")
### BEGIN HIDDEN TESTS
test_rng = np.random.default_rng(1220)  # the tests' own draws, not the notebook's
gap2 = test_rng.uniform(0.5, 80, 200)
v2, lead2 = test_rng.uniform(0, 20, 200), test_rng.uniform(0, 20, 200)
gap2[:10] = np.inf
s0_2 = 3.0
w2 = np.maximum(v2 - lead2, 0.0)
want2 = np.array([0.0 if (not math.isfinite(g) or w == 0) else
                  (math.inf if g <= s0_2 else w * w / (2 * (g - s0_2)))
                  for g, w in zip(gap2, w2)])   # the reference, before the call
got2 = np.asarray(braking_needed(gap2, v2, lead2, s0=s0_2), dtype=float)
assert got2.shape == (200,), f"200 cases: expected 200 decelerations, got shape {got2.shape}"
fin = np.isfinite(want2)
assert np.array_equal(np.isinf(got2), ~fin) and np.allclose(got2[fin], want2[fin], rtol=1e-9), (
    f"200 random gaps and speeds, s0 = 3: expected {np.round(want2[10:14], 4).tolist()} ..., "
    f"got {np.round(got2[10:14], 4).tolist()} ...")
# braking at the answer from gap g, closing at w, the gap's smallest value is s0
g, w = 40.0, 9.0
b = float(braking_needed(g, 9.0, 0.0, s0=s0_2))
tt = np.linspace(0.0, w / b, 20001)
closest = float(np.min(g - w * tt + 0.5 * b * tt**2))
assert abs(closest - s0_2) < 1e-6, (
    f"gap 40 m, closing at 9 m/s, s0 = 3: braking at your b the gap must end at 3 m, "
    f"got {closest:.4f} m")
### END HIDDEN TESTS
# %% grade id=ex12_2_lane_tests points=2
s, t = 2, 10
sit = expert.situation(s, t, train.ego[s, t], expert.steps(s)[t].speed)
got = np.asarray(lane(sit), dtype=float)
assert got.shape == (5,), f"expected 5 values, got shape {got.shape}"
moved = train.ego[s, t] + np.array([-0.5 * math.sin(train.ego[s, t, 2]),
                                    0.5 * math.cos(train.ego[s, t, 2]), 0.0])
got_moved = np.asarray(lane(expert.situation(s, t, moved, sit.ego.v)), dtype=float)
assert abs((got_moved[0] - got[0]) - 0.5) < 0.05, (
    f"scene {s}, step {t}: the ego moved 0.5 m to its left; expected lateral to grow by about "
    f"0.5 m, got {got[0]:.3f} -> {got_moved[0]:.3f}")
assert abs((got_moved[2] - got[2]) + 0.5) < 0.05, (
    f"same move: the path 5 m ahead is now 0.5 m further to the ego's right; expected ahead_5 "
    f"to fall by about 0.5, got {got[2]:.3f} -> {got_moved[2]:.3f}")
### BEGIN HIDDEN TESTS
test_rng = np.random.default_rng(1221)  # the tests' own draws, not the notebook's


def lane_ref(sit):  # the tests' own geometry
    x, y, yaw = (float(q) for q in sit.pose)
    (px, py), h = sit.path.pose(float(sit.ego.s))
    head = (yaw - h + math.pi) % (2 * math.pi) - math.pi
    out = [math.cos(h) * (y - py) - math.sin(h) * (x - px), head]
    for d in (5.0, 10.0, 20.0):
        (qx, qy), _ = sit.path.pose(float(sit.ego.s) + d)
        out.append(math.cos(yaw) * (qy - y) - math.sin(yaw) * (qx - x))
    return np.array(out)


for s in range(len(train)):
    for t in (1, 12, 25, 38):
        pose = train.ego[s, t] + test_rng.normal(0, (0.4, 0.4, 0.15))
        try:
            sit = expert.situation(s, t, pose, float(test_rng.uniform(0, 12)))
        except ValueError:  # off the drivable area: the expert cannot be asked there
            continue
        want, got = lane_ref(sit), np.asarray(lane(sit), dtype=float)
        assert np.allclose(got, want, rtol=1e-9, atol=1e-9), (
            f"scene {s}, step {t}, a perturbed pose {np.round(pose, 2).tolist()}: expected "
            f"[lateral, heading, ahead_5, ahead_10, ahead_20] = {np.round(want, 4).tolist()}, "
            f"got {np.round(got, 4).tolist()}")
### END HIDDEN TESTS


# %% [markdown]
# ## Exercise 12.3 — two ways to ask which input matters
# The tutorial dropped two input groups and drove the learners closed loop. Build the whole
# table open loop, which is cheap: each learner is trained on the demonstrations and scored
# on the validation states; then ask the same question a second way, without retraining.
#
# * `ablation_table(X, Y, Xv, Yv, groups, steps)` returns a dict: the row `"all inputs"`,
#   then one row `"without <group>"` per group of `groups`, in that order; each row is the
#   tuple `(rmse_acceleration, rmse_yaw_rate)` (floats), the root mean squared error of
#   each output on the validation states `Xv` (labels `Yv`) of the tutorial's learner
#   trained on `X, Y` without that group, at a smaller size: two hidden layers of 16,
#   `steps` steps, `seed=0`.
# * `shuffled_rmse(model, Xv, Yv, group, seed)`: keep one trained learner `model` (every
#   input) and break the link between one group and the outputs instead: give every
#   validation state the values of that group's features of another state, by the rows of
#   one permutation `np.random.default_rng(seed).permutation(len(Xv))` (the same for all of
#   the group's columns; the other columns stay), and return the learner's two RMSEs
#   `(acceleration, yaw rate)` as floats on those states. Raise `ValueError` naming `group`
#   for a name that is not a group of `P.FEATURE_GROUPS`.
#
# The written answer below compares the two readings.
#
# <details><summary>Hint 1 (the idea)</summary>
#
# The ablation retrains, so the learner can lean on another input that carries the same
# information; shuffling keeps the learner and only takes the information away from it.
# A removal that costs much is a row with a large error: compare the rows with each other.
# </details>
#
# <details><summary>Hint 2 (the method)</summary>
#
# The tutorial's section 4 shows how a group is dropped. For the shuffle, find the group's
# columns in the feature vector from the names, and work on a copy of the states.
# </details>

# %% solution id=ex12_3 title="Two ways to ask which input matters"
def ablation_table(X, Y, Xv, Yv, groups, steps):
    ### BEGIN SOLUTION
    table = {}
    for group in [None, *groups]:
        model = P.fit_privileged(X, Y, drop=[] if group is None else [group], hidden=(16, 16),
                                 steps=steps, seed=0)
        rmse = np.sqrt(((P.predict(model, Xv) - Yv) ** 2).mean(axis=0))
        table["all inputs" if group is None else f"without {group}"] = (float(rmse[0]),
                                                                        float(rmse[1]))
    return table
    ### END SOLUTION


def shuffled_rmse(model, Xv, Yv, group, seed):
    ### BEGIN SOLUTION
    if group not in P.FEATURE_GROUPS:
        raise ValueError(f"group must be one of {list(P.FEATURE_GROUPS)}, got group={group!r}")
    cols = [P.FEATURES.index(name) for name in P.FEATURE_GROUPS[group]]
    order = np.random.default_rng(seed).permutation(len(Xv))
    Xs = np.array(Xv, copy=True)
    Xs[:, cols] = Xs[order][:, cols]
    rmse = np.sqrt(((P.predict(model, Xs) - Yv) ** 2).mean(axis=0))
    return float(rmse[0]), float(rmse[1])
    ### END SOLUTION

# %% grade id=ex12_3_table_tests points=2
got = ablation_table(X[:300], Y[:300], Xv, Yv, ["leader"], 60)
assert list(got) == ["all inputs", "without leader"], (
    f"groups ['leader']: expected the rows ['all inputs', 'without leader'], got {list(got)}")
for name, row in got.items():
    assert len(row) == 2 and all(math.isfinite(v) and v > 0 for v in row), (
        f"{name}: expected two positive RMSEs (acceleration, yaw rate), got {row!r}")
assert got["without leader"] != got["all inputs"], "dropping a group changes the learner"
assert ablation_table(X[:300], Y[:300], Xv, Yv, ["leader"], 60) == got, (
    "the same call must give the same table (seed=0 in every fit)")
### BEGIN HIDDEN TESTS
got = ablation_table(X[100:500], Y[100:500], Xv[:80], Yv[:80], ["lane", "history"], 40)
assert list(got) == ["all inputs", "without lane", "without history"], list(got)
for name, drop in (("all inputs", []), ("without lane", ["lane"]),
                   ("without history", ["history"])):
    ref = P.fit_privileged(X[100:500], Y[100:500], drop=drop, hidden=(16, 16), steps=40, seed=0)
    want = np.sqrt(((P.predict(ref, Xv[:80]) - Yv[:80]) ** 2).mean(axis=0))
    row = got[name]
    assert isinstance(row, tuple) and len(row) == 2 and all(type(v) is float for v in row), (
        f"{name}: expected a tuple of two floats, got {row!r}")
    assert np.allclose(row, want, rtol=1e-9), (
        f"{name}, 40 steps on states 100-500, 80 validation states: expected "
        f"{np.round(want, 4).tolist()}, got {np.round(row, 4).tolist()}")
### END HIDDEN TESTS


# %% grade id=ex12_3_shuffle_tests points=2
model3 = P.fit_privileged(X[:400], Y[:400], hidden=(16, 16), steps=60, seed=0)
base3 = np.sqrt(((P.predict(model3, Xv) - Yv) ** 2).mean(axis=0))
got3 = shuffled_rmse(model3, Xv, Yv, "lane", 0)
assert len(got3) == 2 and all(type(v) is float for v in got3), (
    f"expected a tuple of two floats (acceleration, yaw rate), got {got3!r}")
assert got3[1] > base3[1], (
    f"a learner of 60 steps, the lane group shuffled with seed 0: expected a yaw-rate RMSE above "
    f"the unshuffled {base3[1]:.4f} rad/s, got {got3[1]:.4f}")
assert shuffled_rmse(model3, Xv, Yv, "lane", 0) == got3, "the same seed must give the same RMSEs"
try:
    shuffled_rmse(model3, Xv, Yv, "weather", 0)
except ValueError as err:
    assert "group" in str(err), f"group='weather': the ValueError must name 'group', got {err}"
else:
    raise AssertionError("group='weather' is not a group: expected a ValueError")
### BEGIN HIDDEN TESTS
for group, seed in (("leader", 3), ("speed", 5), ("history", 0)):
    cols = [P.FEATURES.index(n) for n in P.FEATURE_GROUPS[group]]
    order = np.random.default_rng(seed).permutation(len(Xv))
    Xs = np.array(Xv, copy=True)
    Xs[:, cols] = np.asarray(Xv)[order][:, cols]
    want = np.sqrt(((P.predict(model3, Xs) - Yv) ** 2).mean(axis=0))   # before the call
    got = shuffled_rmse(model3, Xv, Yv, group, seed)
    assert np.allclose(got, want, rtol=1e-6), (
        f"the group {group} shuffled with seed {seed}: expected RMSEs "
        f"{np.round(want, 5).tolist()}, got {np.round(got, 5).tolist()}")
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 12.4 — faded history at another decay
# `world.RasterConfig(history=H)` draws the boxes of the last $H$ steps at brightness
# $1 - j/(H+1)$ for the box $j$ steps ago. Another convention fades geometrically: the box
# $j$ steps ago at $r^j$ for a decay $0 < r < 1$, so that a longer history never makes the
# newest past box fainter.
#
# Write `faded_boxes(ego, ado, ado_valid, t, steps, decay)` for one track (`ego (T, 3)`,
# `ado (T, A, 5)`, `ado_valid (T, A)`) and frame `t`. Return the tuple
# `(ego_past, ego_brightness, ado_past, ado_brightness)`: for $j = 1, \dots,$ `steps` with
# $t - j \ge 0$, the ego's pose at $t - j$ (rows of `ego_past`, shape `(n, 3)`) and every
# ado box valid at $t - j$ in slot order (rows of `ado_past`, shape `(m, 5)`), ordered by
# $j$ first; each box's brightness is `decay ** j` (arrays of shapes `(n,)` and `(m,)`).
# Raise `ValueError` naming the parameter when `decay` is not strictly between 0 and 1,
# `steps` is below 1 or `t` is not a step of the track.
#
# `world.history.history_of` and `world.history.latest_history` are switched off while this
# exercise is graded.
#
# <details><summary>Hint 1 (the idea)</summary>
#
# The boxes are those of earlier rows of the same arrays; only which rows, which slots and
# how bright change with `t`, `steps` and `decay`.
# </details>
#
# <details><summary>Hint 2 (the method)</summary>
#
# Count, for each `j`, whether step $t - j$ exists; a boolean row of `ado_valid` picks the
# valid slots of a step in slot order. Near the start of a track the answer may be empty:
# empty arrays must still have the shapes `(0, 3)` and `(0, 5)`.
# </details>

# %% solution id=ex12_4 title="Faded history at another decay" forbids="minimanc.world.history.history_of,minimanc.world.history.latest_history"  # noqa: E501
def faded_boxes(ego, ado, ado_valid, t, steps, decay):
    ### BEGIN SOLUTION
    ego, ado, ado_valid = np.asarray(ego), np.asarray(ado), np.asarray(ado_valid, dtype=bool)
    if not 0.0 < decay < 1.0:
        raise ValueError(f"decay must be strictly between 0 and 1, got decay={decay!r}")
    if steps < 1:
        raise ValueError(f"steps must be >= 1, got steps={steps!r}")
    if not 0 <= t < len(ego):
        raise ValueError(f"t must be a step in [0, {len(ego)}), got t={t!r}")
    ego_past, ego_b, ado_past, ado_b = [], [], [], []
    for j in range(1, min(steps, t) + 1):
        ego_past.append(ego[t - j])
        ego_b.append(decay ** j)
        boxes = ado[t - j][ado_valid[t - j]]
        ado_past.extend(boxes)
        ado_b.extend([decay ** j] * len(boxes))
    return (np.array(ego_past, dtype=float).reshape(-1, 3), np.array(ego_b, dtype=float),
            np.array(ado_past, dtype=float).reshape(-1, 5), np.array(ado_b, dtype=float))
    ### END SOLUTION

# %% grade id=ex12_4_tests points=3
s4, t4 = 1, 12
got = faded_boxes(val.ego[s4], val.ado[s4], val.ado_valid[s4], t4, 3, 0.5)
assert isinstance(got, tuple) and len(got) == 4, (
    "expected (ego_past, ego_brightness, ado_past, ado_brightness)")
e4, eb4, a4, ab4 = (np.asarray(x, dtype=float) for x in got)
assert e4.shape == (3, 3) and np.allclose(eb4, [0.5, 0.25, 0.125]), (
    f"frame 12, 3 steps, decay 0.5: expected 3 ego poses at brightness [0.5, 0.25, 0.125], got "
    f"shape {e4.shape}, brightness {np.round(eb4, 4).tolist()}")
assert np.allclose(e4[0], val.ego[s4, 11]), "the first past pose is the step before the frame"
n4 = int(val.ado_valid[s4, 9:12].sum())
assert a4.shape == (n4, 5) and ab4.shape == (n4,), (
    f"expected the {n4} ado boxes valid at steps 11, 10, 9, got shapes {a4.shape}, {ab4.shape}")
### BEGIN HIDDEN TESTS
test_rng = np.random.default_rng(1240)  # the tests' own draws, not the notebook's
for s, t, steps, decay in ((0, 0, 2, 0.5), (2, 1, 4, 0.3), (3, 39, 8, 0.8), (4, 20, 1, 0.9)):
    ego, ado, valid = val.ego[s], val.ado[s], val.ado_valid[s].copy()
    valid &= test_rng.uniform(size=valid.shape) < 0.7  # drop some slots: order must hold
    js = [j for j in range(1, steps + 1) if t - j >= 0]
    want_e = np.array([ego[t - j] for j in js]).reshape(-1, 3)
    want_a = np.array([ado[t - j, k] for j in js for k in range(ado.shape[1])
                       if valid[t - j, k]]).reshape(-1, 5)
    want_ab = np.array([decay ** j for j in js for k in range(ado.shape[1]) if valid[t - j, k]])
    got = [np.asarray(x, dtype=float) for x in faded_boxes(ego, ado, valid, t, steps, decay)]
    case = f"scene {s}, frame {t}, {steps} steps, decay {decay}"
    assert got[0].shape == want_e.shape and np.allclose(got[0], want_e), (
        f"{case}: expected {len(js)} ego poses (shape {want_e.shape}), got shape {got[0].shape}")
    assert np.allclose(got[1], [decay ** j for j in js]), (
        f"{case}: expected ego brightness {np.round([decay ** j for j in js], 4).tolist()}, got "
        f"{np.round(got[1], 4).tolist()}")
    assert got[2].shape == want_a.shape and np.allclose(got[2], want_a), (
        f"{case}: expected {len(want_a)} ado boxes by step then slot (shape {want_a.shape}), "
        f"got shape {got[2].shape}")
    assert got[3].shape == want_ab.shape and np.allclose(got[3], want_ab), (
        f"{case}: expected one brightness decay**j per ado box, got {got[3][:6]}")
for kwargs, name in (({"decay": 1.0}, "decay"), ({"decay": 0.0}, "decay"),
                     ({"steps": 0}, "steps"), ({"t": 40}, "t"), ({"t": -1}, "t")):
    args = {"t": 5, "steps": 2, "decay": 0.5, **kwargs}
    try:
        faded_boxes(val.ego[0], val.ado[0], val.ado_valid[0], args["t"], args["steps"],
                    args["decay"])
    except ValueError as err:
        assert name in str(err), f"{kwargs}: the ValueError must name {name!r}, got {err}"
    else:
        raise AssertionError(f"{kwargs}: expected a ValueError")
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 12.5 — an open experiment: a small input set
# The raster of one frame can show only some of the expert's 13 numbers. Before asking an
# image model for all of them, find out how few the learner needs. Choose the features to
# remove: `small_inputs()` returns a tuple of feature names (of `P.FEATURES`) passed as
# `P.fit_privileged(X, Y, without=..., hidden=(16, 16), steps=600, seed=0)`, such that
#
# * at least 5 of the 13 features are removed;
# * the learner's open-loop RMSE on the validation states is within 15 % of the learner with
#   every input, for both outputs (acceleration and yaw rate).
#
# Use your `ablation_table` (groups) and `P.fit_privileged(..., without=[...])` (single features) to
# choose (2 points; the grade cell fits both learners itself). Then answer the written
# question below it.

# %% solution id=ex12_5 title="A small input set"
def small_inputs():
    ### BEGIN SOLUTION
    # flags and distances the others imply, the farthest path points, the copycat input:
    # the table of 12.3 shows which groups cost little; single features checked by P.fit_privileged
    return ("has_leader", "has_stop", "ahead_5", "ahead_20", "dv")
    ### END SOLUTION

# %% grade id=ex12_5_tests points=2
chosen = small_inputs()
assert isinstance(chosen, tuple) and all(c in P.FEATURES for c in chosen), (
    f"expected a tuple of names of P.FEATURES, got {chosen!r}")
assert len(set(chosen)) >= 5, f"expected at least 5 features removed, got {len(set(chosen))}"


def rmse5(without):  # the grade cell's own fit and score
    m = P.fit_privileged(X, Y, without=list(without), hidden=(16, 16), steps=600, seed=0)
    return np.sqrt(((P.predict(m, Xv) - Yv) ** 2).mean(axis=0))


every, small = rmse5(()), rmse5(chosen)
assert np.all(small <= 1.15 * every), (
    f"without {sorted(set(chosen))}: expected RMSE within 15 % of every input's "
    f"{np.round(every, 4).tolist()}, got {np.round(small, 4).tolist()}")

# %% [markdown]
# **Written question (graded by hand, 3 points).** Which features did you remove, and why
# could the learner do without them? In your ablation table (12.3), which group's removal
# costs the most acceleration error open loop, and does shuffling that group
# (`shuffled_rmse`) rank it the same way? Say why the two readings can differ. What does
# `research/why_it_crashes/REPORT.md` ("Ablation") report for the same group closed loop?
# Explain the difference, and say which of your removals you would check closed loop before
# building an image model on them.

# %% [markdown] answer id=ex12_w title="Reading an ablation" points=3
# ### BEGIN SOLUTION
# I removed `has_leader` and `has_stop` (the clipped distances already say "nothing within
# 60 m"), `ahead_5` and `ahead_20` (the path's curvature is in `ahead_10`, `heading` and
# `a_curve` together) and `dv` (open loop the next acceleration follows mostly from the last
# one and the gap). Open loop, removing `history` (the last acceleration) costs the most
# acceleration error: the human's acceleration changes slowly (reaction delay, bounded
# jerk), so the last one predicts the next. Shuffling `history` raises the acceleration
# error of the learner with every input the most as well. The two readings answer different
# questions: shuffling asks what *this* learner uses (it still trusts the shuffled input and
# is misled by it), retraining asks what the learner *needs* (it can lean on another input
# that carries the same information). They differ most for information two groups share:
# the flags and the clipped distances, or the curve and the path points ahead. Closed loop
# the committed ablation says the opposite of the open-loop ranking:
# without `history` the learner collides *less* than with every input. A learner that leans
# on its last acceleration copies its own previous command (the copycat of causal confusion,
# de Haan et al. 2019); on the human's states that is right, in its own states it keeps
# accelerating when it should brake. An open-loop score, retrained or shuffled, judges each
# prediction on the human's states and cannot see that. The removal I would check closed
# loop first is `dv`: the closing speed matters in the rare states just before a rear-end
# collision, which barely move an RMSE over all states, and the ablation's `leader` row shows
# what losing it costs in collisions.
# ### END SOLUTION

# %% [markdown]
# ## Exercise 12.6 — a masked loss that weighs every target alike, and its gradient
# Tutorial section 7 trains a perception on the expert's numbers with a mask: the gap and
# the closing speed count only where there is a leader. The library's loss
# (`minimanc.train.perception.masked_perception_loss`) sums the counted squared errors and
# divides by *every* entry, counted or not, so a target that counts in few states (the gap:
# only where a car leads) weighs less than one that counts everywhere (the own speed).
#
# Write `masked_mse(out, z, mask)` for predictions `out (N, K)`, targets `z (N, K)` and a
# boolean `mask (N, K)`: for each target `k`, the mean of the squared error over the
# states where it counts (a target that counts in no state adds 0), then the mean of those
# `K` numbers. Return the tuple `(loss, grad)`: the loss as a float and its gradient with
# respect to `out`, an array `(N, K)`, which you derive and write out (no autodiff). A
# masked target's value is never read: where `mask` is False, `z` may hold anything, `nan`
# included, and neither the loss nor the gradient may change.
#
# `masked_perception_loss` is switched off while this exercise is graded.
#
# <details><summary>Hint 1 (the idea)</summary>
#
# Each prediction enters one squared error, inside one target's mean, inside the mean over
# the targets: the chain rule has three factors. Which entries' gradient must be zero?
# </details>
#
# <details><summary>Hint 2 (the method)</summary>
#
# Count the states that count per target (a column sum of the mask) and guard the empty
# column. `0 * nan` is `nan`: pick the errors with `np.where` before squaring them. Check
# your gradient by central differences, one entry at a time.
# </details>

# %% solution id=ex12_6 title="A masked loss and its gradient" forbids="minimanc.train.perception.masked_perception_loss"  # noqa: E501
def masked_mse(out, z, mask):
    ### BEGIN SOLUTION
    out, z = np.asarray(out, dtype=float), np.asarray(z, dtype=float)
    m = np.asarray(mask, dtype=bool)
    err = np.where(m, out - z, 0.0)
    counted = np.maximum(m.sum(axis=0), 1)          # states per target (an empty one: 1)
    K = out.shape[1]
    loss = float(((err ** 2).sum(axis=0) / counted).sum() / K)
    grad = 2.0 * err / (K * counted)                # zero where the mask is False
    return loss, grad
    ### END SOLUTION

# %% grade id=ex12_6_loss_tests points=2
out6 = np.array([[1.0, 5.0], [3.0, 0.0]])
z6 = np.array([[0.0, np.nan], [1.0, 2.0]])
mask6 = np.array([[True, False], [True, True]])
got6 = masked_mse(out6, z6, mask6)
assert isinstance(got6, tuple) and len(got6) == 2, "expected the tuple (loss, grad)"
assert type(got6[0]) is float, f"expected the loss as a float, got {type(got6[0]).__name__}"
assert math.isclose(got6[0], 3.25), (
    "two states, two targets; the first counts in both states (errors 1 and 2), the second "
    f"only in the second state (error -2, its target nan where it does not count): expected "
    f"the mean of 2.5 and 4.0 = 3.25, got {got6[0]!r}")
### BEGIN HIDDEN TESTS
test_rng = np.random.default_rng(1260)  # the tests' own draws, not the notebook's
for N, K, p in ((7, 3, 0.6), (40, 12, 0.3), (5, 4, 0.0), (9, 2, 1.0)):
    out_h = test_rng.normal(size=(N, K))
    z_h = test_rng.normal(size=(N, K))
    m_h = test_rng.uniform(size=(N, K)) < p
    m_h[:, 0] = True                                # one target that counts everywhere
    if K > 2:
        m_h[:, -1] = False                          # and one that counts nowhere
    z_h[~m_h] = np.nan
    e_h = np.where(m_h, out_h - z_h, 0.0)
    want = float(np.mean((e_h ** 2).sum(0) / np.maximum(m_h.sum(0), 1)))  # before the call
    got = masked_mse(out_h, z_h, m_h)
    case = f"{N} states, {K} targets, mask share {p}"
    assert type(got[0]) is float and math.isclose(got[0], want, rel_tol=1e-9), (
        f"{case}: expected the loss {want:.6f}, got {got[0]!r}")
# the loss of a target is a mean: repeating every state changes nothing
out_h, z_h = test_rng.normal(size=(6, 3)), test_rng.normal(size=(6, 3))
m_h = test_rng.uniform(size=(6, 3)) < 0.5
m_h[0] = True
want = masked_mse(out_h, z_h, m_h)[0]
got = masked_mse(np.tile(out_h, (3, 1)), np.tile(z_h, (3, 1)), np.tile(m_h, (3, 1)))[0]
assert math.isclose(got, want, rel_tol=1e-9), (
    f"every state repeated three times: expected the same loss {want:.6f}, got {got:.6f} "
    "(each target's loss is a mean over its counted states)")
### END HIDDEN TESTS

# %% grade id=ex12_6_grad_tests points=2
out6g = np.array([[1.0, 5.0, 0.5], [3.0, 0.0, -1.0]])
z6g = np.array([[0.0, np.nan, 2.0], [1.0, 2.0, np.nan]])
mask6g = np.array([[True, False, True], [True, True, False]])
g6 = np.asarray(masked_mse(out6g, z6g, mask6g)[1], dtype=float)
assert g6.shape == (2, 3) and np.all(np.isfinite(g6)), (
    f"two states, three targets, nan where a target does not count: expected a finite "
    f"gradient of shape (2, 3), got {g6.shape}: {g6}")
assert g6[0, 1] == 0.0 and g6[1, 2] == 0.0, (
    f"the same case: the entries that do not count must have gradient 0, got {g6[0, 1]} and "
    f"{g6[1, 2]}")
eps6 = 1e-6
for i6, k6 in ((1, 0), (1, 1), (0, 2)):
    bump6 = np.zeros((2, 3))
    bump6[i6, k6] = eps6
    fd6 = (masked_mse(out6g + bump6, z6g, mask6g)[0]
           - masked_mse(out6g - bump6, z6g, mask6g)[0]) / (2 * eps6)
    assert abs(g6[i6, k6] - fd6) < 1e-6, (
        f"the same case, entry ({i6}, {k6}): central differences of your loss give "
        f"{fd6:.6f}, your gradient {g6[i6, k6]:.6f}")
### BEGIN HIDDEN TESTS
test_rng = np.random.default_rng(1261)  # the tests' own draws, not the notebook's
for N, K, p in ((6, 3, 0.5), (11, 5, 0.25), (4, 2, 1.0)):
    out_h = test_rng.normal(size=(N, K))
    z_h = test_rng.normal(size=(N, K))
    m_h = test_rng.uniform(size=(N, K)) < p
    m_h[0, 0] = True
    if K > 2:
        m_h[:, 1] = False
    z_h[~m_h] = np.nan
    counted_h = np.maximum(m_h.sum(0), 1)
    want = 2.0 * np.where(m_h, out_h - z_h, 0.0) / (K * counted_h)   # before the call
    got = np.asarray(masked_mse(out_h, z_h, m_h)[1], dtype=float)
    case = f"{N} states, {K} targets, mask share {p}"
    assert got.shape == (N, K) and np.allclose(got, want, rtol=1e-9, atol=1e-12), (
        f"{case}: expected the gradient {np.round(want[:2], 4).tolist()} ..., "
        f"got {np.round(got[:2], 4).tolist()} ...")
    fd = np.zeros((N, K))
    for i in range(N):
        for k in range(K):
            b = np.zeros((N, K))
            b[i, k] = 1e-6
            fd[i, k] = (masked_mse(out_h + b, z_h, m_h)[0]
                        - masked_mse(out_h - b, z_h, m_h)[0]) / 2e-6
    assert np.allclose(got, fd, atol=1e-6), (
        f"{case}: your gradient disagrees with central differences of your loss by "
        f"{np.abs(got - fd).max():.2e}")
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 12.7 — the history planes, from the poses
# The learner's raster (tutorial section 7) draws the ego and the other vehicles at t−1,
# t−2, … each in a binary plane of its own, every box seen in the ego's frame at t. Draw
# those planes yourself.
#
# Write `history_planes(ego_pose, past, cfg)`: `ego_pose` is the ego's world pose
# `[x, y, yaw]` at t, `past` a `world.history.History` of one frame (`past.ego (1, H, 3)`,
# `past.ego_valid (1, H)`, `past.ado (1, H, A, 5)` world boxes `[x, y, yaw, length, width]`,
# `past.ado_valid (1, H, A)`, index `j − 1` for the step `j` steps ago) and `cfg` a
# `world.RasterConfig` (its `size` rows and `width` columns, `metres_ahead`,
# `metres_side`, `res_row`, `res_col`, `ego_length`, `ego_width`; the pixel convention of
# its module docstring, `help(world.raster)`). Return a dict with the keys `"ego_t-j"` and
# `"vehicles_t-j"` for `j = 1, …, H`, each a uint8 array `(cfg.size, cfg.width)`: 1 where
# the pixel's *centre* lies inside (edges included) one of that step's valid boxes — the
# ego's own past box is `cfg.ego_length` by `cfg.ego_width` at its past pose — else 0.
#
# The grade compares your planes with the library's rasteriser's on frames of scenes you
# have not seen, in two views; a pixel whose centre lies on a box's edge within rounding may
# go either way, so one differing pixel per plane is forgiven. `world.rasterize`,
# `world.rasterize_batch` and `world.raster.box_mask` are switched off while this exercise is
# graded.
#
# <details><summary>Hint 1 (the idea)</summary>
#
# Two changes of frame: a box's centre and heading from the world into the ego's frame at
# t, then each pixel centre into the box's own frame, where "inside" is two comparisons.
# </details>
#
# <details><summary>Hint 2 (the method)</summary>
#
# `cfg.pixel_centres()` gives the ego-frame coordinates of every pixel centre, `(H, W)`
# each; broadcast them against the boxes of a step. Start from a box you can check by hand:
# the ego standing still draws its past box where its box is now.
# </details>

# %% [markdown]
# Two scenes of the exercises' draw, drawn as the learner's raster, to check your planes on:

# %%
LEARNER = world.RasterConfig(encoding="channels", route=True, history=2)
seen = world.generate(2, seed=1, raster=LEARNER, workers=1)
print("planes:", ", ".join(LEARNER.channel_names))

# %% solution id=ex12_7 title="The history planes, from the poses" forbids="minimanc.world.raster.rasterize,minimanc.world.raster.rasterize_batch,minimanc.world.raster.box_mask"  # noqa: E501
def history_planes(ego_pose, past, cfg):
    ### BEGIN SOLUTION
    x0, y0, yaw0 = (float(q) for q in ego_pose)
    X, Y = cfg.pixel_centres()
    c0, s0 = math.cos(yaw0), math.sin(yaw0)

    def inside(boxes):  # boxes (n, 5) in the world -> pixels inside any of them
        hit = np.zeros(X.shape, dtype=bool)
        for bx, by, byaw, length, width in np.asarray(boxes, dtype=float).reshape(-1, 5):
            ex, ey = c0 * (bx - x0) + s0 * (by - y0), -s0 * (bx - x0) + c0 * (by - y0)
            c, s = math.cos(byaw - yaw0), math.sin(byaw - yaw0)
            u = c * (X - ex) + s * (Y - ey)
            v = -s * (X - ex) + c * (Y - ey)
            hit |= (np.abs(u) <= length / 2) & (np.abs(v) <= width / 2)
        return hit.astype(np.uint8)

    out = {}
    for j in range(1, past.steps + 1):
        ego = past.ego[0, j - 1][None] if past.ego_valid[0, j - 1] else np.zeros((0, 3))
        size = np.broadcast_to([cfg.ego_length, cfg.ego_width], (len(ego), 2))
        out[f"ego_t-{j}"] = inside(np.concatenate([ego, size], axis=1))
        out[f"vehicles_t-{j}"] = inside(past.ado[0, j - 1][past.ado_valid[0, j - 1]])
    return out
    ### END SOLUTION

# %% grade id=ex12_7_tests points=3
s7, t7 = 0, 15
past7 = world.history.history_of(seen.ego[s7], seen.ado[s7], seen.ado_valid[s7], 2, frames=[t7])
got7 = history_planes(seen.ego[s7, t7], past7, seen.raster)
names7 = [f"{who}_t-{j}" for who in ("ego", "vehicles") for j in (1, 2)]
assert isinstance(got7, dict) and sorted(got7) == sorted(names7), (
    f"two past steps: expected the keys {sorted(names7)}, got {sorted(got7)}")
stored7 = world.encodings.planes(seen.bev[s7, t7], seen.raster)
for name in names7:
    plane = np.asarray(got7[name])
    assert plane.shape == (64, 64), f"{name}: expected shape (64, 64), got {plane.shape}"
    wrong = int((plane != stored7[..., seen.raster.channel_names.index(name)]).sum())
    assert wrong <= 1, (
        f"scene {s7}, frame {t7} of the learner's raster: {name} differs from the stored "
        f"frame's plane in {wrong} pixels")
### BEGIN HIDDEN TESTS
held = world.generate(4, seed=2, raster=LEARNER, workers=1)       # scenes never shown
corridor = world.generate(3, seed=3, workers=1, raster=world.RasterConfig.from_extent(
    60.0, 12.5, 0.5, encoding="channels", history=3))
for ds7, frames in ((held, ((0, 0), (0, 1), (1, 9), (2, 27), (3, 39))),
                    (corridor, ((0, 2), (1, 20), (2, 33)))):
    cfg7 = ds7.raster
    H7 = cfg7.history
    for s, t in frames:
        stored = world.encodings.planes(ds7.bev[s, t], cfg7)
        want = {n: stored[..., cfg7.channel_names.index(n)].copy()
                for n in cfg7.channel_names if "_t-" in n}          # before the call
        past = world.history.history_of(ds7.ego[s], ds7.ado[s], ds7.ado_valid[s], H7,
                                        frames=[t])
        got = history_planes(ds7.ego[s, t], past, cfg7)
        case = f"a held-out scene {s}, frame {t}, a {cfg7.size}x{cfg7.width} view, {H7} steps"
        assert isinstance(got, dict) and sorted(got) == sorted(want), (
            f"{case}: expected the keys {sorted(want)}, got {sorted(got)}")
        for name, w in want.items():
            g = np.asarray(got[name])
            assert g.shape == w.shape, f"{case}, {name}: expected shape {w.shape}, got {g.shape}"
            wrong = int((g != w).sum())
            assert wrong <= 1, (
                f"{case}, {name}: {wrong} pixels differ from the library's rasteriser "
                f"({int(w.sum())} pixels set there, {int((g != 0).sum())} in yours)")
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 12.8 — how far ahead must the raster reach?
# A leader counts for the perception only where its box reaches into the raster (tutorial
# section 7): its *rear* — the nearest point of the box along the ego's heading — less than
# `metres_ahead` ahead, and its centre less than `metres_side` to either side. The course's
# view reaches 40 m ahead; the human brakes for leaders further away. Design the view from
# the data: `leaders` below holds the box of the leader the human perceives in every state
# of the training scenes, in the ego frame (`diagnose.leader_boxes`: `[x, y, yaw, length,
# width]` with `yaw` relative to the ego's heading, `nan` where there is no leader).
#
# Write `view_for(boxes, share, resolution)` for boxes `(..., 5)` (rows of `nan`: no
# leader, ignored). Return `world.RasterConfig.from_extent(ahead, side, resolution,
# encoding="channels", route=True, history=2)` where `ahead` is the smallest positive
# multiple of `resolution` for which the fraction of the leaders whose rear lies less than
# `ahead` in front of the ego is at least `share`, and `side` the smallest positive multiple
# of `resolution` for which the fraction of the leaders whose centre lies less than `side`
# to the side (either side) is at least `share`. Raise `ValueError` naming `share` unless
# `0 < share <= 1`, and naming `boxes` when there is no leader.
#
# `diagnose.perception_targets` is switched off while this exercise is graded.
#
# <details><summary>Hint 1 (the idea)</summary>
#
# The rear of a box turned by `yaw` is its centre minus half of the box's extent along the
# ego's heading; a box's extent along an axis is the sum of its two sides' extents along it.
# </details>
#
# <details><summary>Hint 2 (the method)</summary>
#
# Sort the distances: the leader at sorted position `m` (from 1) must be inside for `m` of
# `n` leaders to be. Which multiple of the resolution is the first one *beyond* that
# leader's distance? Check your answer by counting, with your own view, the share it shows.
# </details>

# %% [markdown]
# The leaders of the training scenes (the human re-simulated; a few seconds):

# %%
leaders = diagnose.leader_boxes(train)
found = ~np.isnan(leaders[..., 0])
print(f"{int(found.sum())} of {found.size} training states have a leader")

# %% solution id=ex12_8 title="How far ahead must the raster reach?" forbids="minimanc.diagnose.perception_targets.perception_targets"  # noqa: E501
def view_for(boxes, share, resolution):
    ### BEGIN SOLUTION
    if not 0.0 < share <= 1.0:
        raise ValueError(f"share must be in (0, 1], got share={share!r}")
    b = np.asarray(boxes, dtype=float).reshape(-1, 5)
    b = b[~np.isnan(b).any(axis=1)]
    if not len(b):
        raise ValueError("boxes holds no leader (every row is nan)")
    x, y, yaw, length, width = b.T
    rear = x - 0.5 * (np.abs(np.cos(yaw)) * length + np.abs(np.sin(yaw)) * width)

    def reach(d):  # smallest positive multiple k * resolution with share of d below it
        need = math.ceil(share * len(d) - 1e-9)     # leaders that must be inside
        k = math.floor(np.sort(d)[need - 1] / resolution) + 1
        return max(k, 1) * resolution

    return world.RasterConfig.from_extent(reach(rear), reach(np.abs(y)), resolution,
                                          encoding="channels", route=True, history=2)
    ### END SOLUTION

# %% grade id=ex12_8_tests points=3
view8 = view_for(leaders, 0.9, 1.0)
assert isinstance(view8, world.RasterConfig), f"expected a RasterConfig, got {view8!r}"
assert (view8.encoding, view8.route, view8.history, view8.metres_behind) == (
    "channels", True, 2, 10.0), "the learner's raster: channels, route, 2 past steps, 10 m behind"
for attr in ("metres_ahead", "metres_side"):
    metres = getattr(view8, attr)
    assert math.isclose(metres, round(metres)) and metres >= 1, (
        f"resolution 1 m: {attr} must be a positive whole number of metres, got {metres}")
one = np.array([[30.0, 2.4, 0.0, 4.0, 2.0]])          # one leader, 30 m ahead, straight
view1 = view_for(one, 1.0, 0.5)
assert math.isclose(view1.metres_ahead, 28.5) and math.isclose(view1.metres_side, 2.5), (
    "one leader, centre 30 m ahead and 2.4 m to the left, 4 m long, aligned with the ego, "
    "resolution 0.5 m: its rear is 28 m ahead, so expected 28.5 m ahead and 2.5 m to the "
    f"side, got {view1.metres_ahead} and {view1.metres_side}")
### BEGIN HIDDEN TESTS
test_rng = np.random.default_rng(1280)  # the tests' own draws, not the notebook's


def reach_ref(d, share, res):  # the tests' own count: the first multiple that holds enough
    k = 1
    while np.mean(d < k * res) < share:
        k += 1
    return k * res


rows = leaders.reshape(-1, 5)[~np.isnan(leaders.reshape(-1, 5)[:, 0])]
synthetic = np.column_stack([test_rng.uniform(3, 90, 137), test_rng.normal(0, 6, 137),
                             test_rng.uniform(-math.pi, math.pi, 137),
                             test_rng.uniform(3.5, 12, 137), test_rng.uniform(1.6, 2.6, 137)])
with_nan = np.concatenate([synthetic, np.full((9, 5), np.nan)])[test_rng.permutation(146)]
for boxes8, share8, res8, label in ((leaders, 0.95, 0.78125, "the training leaders"),
                                   (rows, 0.77, 0.5, "the training leaders as rows"),
                                   (with_nan, 0.9, 0.25, "137 turned boxes and 9 nan rows"),
                                   (synthetic[:7], 1.0, 2.0, "7 turned boxes, all")):
    r = boxes8.reshape(-1, 5)
    r = r[~np.isnan(r[:, 0])]
    rear8 = r[:, 0] - 0.5 * (np.abs(np.cos(r[:, 2])) * r[:, 3] + np.abs(np.sin(r[:, 2])) * r[:, 4])
    want_a, want_s = reach_ref(rear8, share8, res8), reach_ref(np.abs(r[:, 1]), share8, res8)
    got = view_for(boxes8, share8, res8)
    case = f"{label}, share {share8}, resolution {res8} m"
    assert isinstance(got, world.RasterConfig), f"{case}: expected a RasterConfig, got {got!r}"
    assert math.isclose(got.metres_ahead, want_a, rel_tol=1e-9), (
        f"{case}: expected {want_a} m ahead, got {got.metres_ahead}")
    assert math.isclose(got.metres_side, want_s, rel_tol=1e-9), (
        f"{case}: expected {want_s} m to the side, got {got.metres_side}")
    want_cfg = world.RasterConfig.from_extent(want_a, want_s, res8, encoding="channels",
                                              route=True, history=2)
    assert (got.size, got.width, got.channel_names) == (want_cfg.size, want_cfg.width,
                                                        want_cfg.channel_names), (
        f"{case}: expected a {want_cfg.size}x{want_cfg.width} raster of the learner's planes, "
        f"got {got.size}x{got.width}, {got.channel_names}")
for share8, name in ((0.0, "share"), (1.5, "share")):
    try:
        view_for(synthetic, share8, 1.0)
    except ValueError as err:
        assert name in str(err), f"share={share8}: the ValueError must name {name!r}, got {err}"
    else:
        raise AssertionError(f"share={share8}: expected a ValueError")
try:
    view_for(np.full((3, 5), np.nan), 0.9, 1.0)
except ValueError as err:
    assert "boxes" in str(err), f"no leader: the ValueError must name 'boxes', got {err}"
else:
    raise AssertionError("boxes without a leader: expected a ValueError")
### END HIDDEN TESTS

# %% [markdown]
# **Written question (graded by hand, 2 points).** Print `view_for(leaders, 0.95, 0.78125)`:
# how far ahead and to the side must the view reach for 95 % of the leaders, and how many
# pixels does it have against the course's 64 × 64 at the same resolution? The human looks
# for a leader up to `25 + 3.5 v` metres ahead: at which speed does your view stop showing
# the leaders it brakes for, and what does the perception then report? What does
# `research/seeing_the_leader/results/perception.md` find for the 60 m view (`reach60`,
# `route60`, `route60_scale`) against the 40 m one, and why could a longer view help only
# with more training scenes?

# %% [markdown] answer id=ex12_8_w title="The view the data asks for" points=2
# ### BEGIN SOLUTION
# On the 22 training scenes the view for 95 % of the leaders reaches about 50 m ahead and
# less than 10 m to each side (the printed `RasterConfig`: a corridor of about 76 × 24
# pixels, fewer than the 64 × 64 square's 4096): the leaders the human follows are in its
# lane, so they are far ahead long before they are far to the side; only curves and
# junctions move them sideways. The human's search reach 25 + 3.5 v passes 40 m at
# v ≈ 4.3 m/s and 50 m at about 7 m/s: above that a leader the human brakes for can lie
# beyond the view, and the perception reports "no leader" there (by the mask of
# `perception_targets`, its presence target is 0 for a leader outside the view), so a
# driver on it brakes late for a slow car far ahead. The study's one-seed screen
# (`perception.md`) found the 60 m view *worse* for the gap than the 40 m one at 300
# scenes (`reach60` against `base`, `route60` against `route`) and better with 600
# (`route60_scale`): a longer picture holds more pixels the network must learn to ignore,
# and the far leaders it adds are the rare states, few in a small dataset, so the extra
# reach pays only once there are enough examples of them.
# ### END SOLUTION

# %% [markdown]
# ## Exercise 12.9 — a probe with more features than states
# Tutorial section 7(c) asks what a backbone's features hold with a linear probe
# (`diagnose.linear_probe`): features standardised on the training states (each one minus
# its mean, divided by its standard deviation plus `1e-8`), a ridge regression
# `y ≈ a w + b` on the standardised features `a` with the penalty `ridge · |w|²` on the
# weights and none on the intercept `b`, scored by `R² = 1 − Σ(y − ŷ)² / Σ(y − ȳ)²` on the
# held-out states (`ȳ` their mean). It solves a system with one equation per feature. A
# flattened backbone or a raster has tens of thousands of features and a few hundred
# states: derive a solution that solves a system with one equation per **state** instead.
#
# Write `probe_r2(Z, y, Z_val, y_val, ridge)` for features `Z (N, D)` and `Z_val (M, D)`,
# quantities `y (N, K)` and `y_val (M, K)` and `ridge > 0`. Return the `K` validation
# `R²` as an array of shape `(K,)`, equal (to 1e-6) to those of the model above, without
# forming any `D × D` matrix. Raise `ValueError` naming `ridge` unless `ridge > 0`.
#
# `diagnose.linear_probe` is switched off while this exercise is graded. The cell after the
# grade cells runs your probe on the raw planes of the learner's raster: 49 152 features
# per state, where a `D × D` system of float64 needs 19 GB.
#
# <details><summary>Hint 1 (the idea)</summary>
#
# Set the derivative of the loss with respect to the intercept to zero: what is `b` when
# the standardised features have mean zero on the training states? Then write the
# weights' normal equations and multiply them from the left by the matrix of standardised
# features: which `N × N` matrix appears?
# </details>
#
# <details><summary>Hint 2 (the method)</summary>
#
# Solve for `N` coefficients, one per training state, and build the weights (or the
# predictions) from them. Check your function against the `(D + 1)`-equation solution on
# a small random case before you trust it on a large one.
# </details>

# %% solution id=ex12_9 title="A probe with more features than states" forbids="minimanc.diagnose.probe.linear_probe"  # noqa: E501
def probe_r2(Z, y, Z_val, y_val, ridge):
    ### BEGIN SOLUTION
    if not ridge > 0:
        raise ValueError(f"ridge must be > 0 (A Aᵀ is singular otherwise), got ridge={ridge!r}")
    Z, Z_val = np.asarray(Z, dtype=float), np.asarray(Z_val, dtype=float)
    y, y_val = np.asarray(y, dtype=float), np.asarray(y_val, dtype=float)
    mu, sd = Z.mean(axis=0), Z.std(axis=0) + 1e-8
    A, A_val = (Z - mu) / sd, (Z_val - mu) / sd
    b = y.mean(axis=0)                                # the intercept: the columns of A sum to 0
    coef = np.linalg.solve(A @ A.T + ridge * np.eye(len(A)), y - b)   # (N, K)
    pred = (A_val @ A.T) @ coef + b                   # w = Aᵀ coef, never formed as D × D
    res = ((y_val - pred) ** 2).sum(axis=0)
    tot = ((y_val - y_val.mean(axis=0)) ** 2).sum(axis=0)
    return 1.0 - res / tot
    ### END SOLUTION

# %% grade id=ex12_9_tests points=3
rng9 = np.random.default_rng(129)
Z9, Zv9 = rng9.normal(size=(12, 5)), rng9.normal(size=(9, 5))
y9 = Z9 @ np.array([[1.0], [0.0], [-2.0], [0.5], [0.0]]) + rng9.normal(0, 0.1, (12, 1))
yv9 = Zv9 @ np.array([[1.0], [0.0], [-2.0], [0.5], [0.0]]) + rng9.normal(0, 0.1, (9, 1))
mu9, sd9 = Z9.mean(0), Z9.std(0) + 1e-8                # the model, with one equation per feature
A9 = np.hstack([(Z9 - mu9) / sd9, np.ones((12, 1))])
w9 = np.linalg.solve(A9.T @ A9 + np.diag([0.5] * 5 + [0.0]), A9.T @ y9)
p9 = np.hstack([(Zv9 - mu9) / sd9, np.ones((9, 1))]) @ w9
want9 = 1 - ((yv9 - p9) ** 2).sum(0) / ((yv9 - yv9.mean(0)) ** 2).sum(0)
got9 = np.asarray(probe_r2(Z9, y9, Zv9, yv9, 0.5), dtype=float)
assert got9.shape == (1,), f"one quantity: expected R² of shape (1,), got {got9.shape}"
assert np.allclose(got9, want9, atol=1e-6), (
    f"12 training states, 5 features, ridge 0.5: expected R² {want9[0]:.6f}, got {got9[0]:.6f}")
try:
    probe_r2(Z9, y9, Zv9, yv9, 0.0)
except ValueError as err:
    assert "ridge" in str(err), f"ridge=0: the ValueError must name 'ridge', got {err}"
else:
    raise AssertionError("ridge=0: expected a ValueError")
### BEGIN HIDDEN TESTS
test_rng = np.random.default_rng(1290)  # the tests' own draws, not the notebook's


def probe_ref(Z, y, Zv, yv, lam):  # the tests' own (D + 1)-equation solution
    mu, sd = Z.mean(0), Z.std(0) + 1e-8
    A = np.hstack([(Z - mu) / sd, np.ones((len(Z), 1))])
    w = np.linalg.solve(A.T @ A + np.diag([lam] * Z.shape[1] + [0.0]), A.T @ y)
    p = np.hstack([(Zv - mu) / sd, np.ones((len(Zv), 1))]) @ w
    return 1 - ((yv - p) ** 2).sum(0) / ((yv - yv.mean(0)) ** 2).sum(0)


for N, M, D, K, lam in ((30, 20, 4, 1, 1.0), (25, 40, 300, 3, 10.0), (50, 30, 2000, 2, 1e3),
                        (8, 8, 8, 1, 1e-3)):
    Z_h, Zv_h = test_rng.normal(size=(N, D)), test_rng.normal(size=(M, D))
    Z_h[:, 0] = 3.0                                   # a feature that never changes
    Zv_h[:, 0] = 3.0
    W_h = test_rng.normal(size=(D, K)) / np.sqrt(D)
    y_h = Z_h @ W_h + 5.0 + test_rng.normal(0, 0.3, (N, K))
    yv_h = Zv_h @ W_h + 5.0 + test_rng.normal(0, 0.3, (M, K))
    want = probe_ref(Z_h, y_h, Zv_h, yv_h, lam)       # before the call
    got = np.asarray(probe_r2(Z_h, y_h, Zv_h, yv_h, lam), dtype=float)
    case = f"{N} states, {D} features, {K} quantities, ridge {lam}"
    assert got.shape == (K,) and np.allclose(got, want, atol=1e-6), (
        f"{case}: expected R² {np.round(want, 6).tolist()}, got {np.round(got, 6).tolist()}")
for lam in (-1.0, 0.0):
    try:
        probe_r2(Z9, y9, Zv9, yv9, lam)
    except ValueError as err:
        assert "ridge" in str(err), f"ridge={lam}: the ValueError must name 'ridge', got {err}"
    else:
        raise AssertionError(f"ridge={lam}: expected a ValueError")
### END HIDDEN TESTS

# %% [markdown]
# Your probe on the raw planes of the learner's raster (tutorial section 7: `route=True`,
# `history=2`) of the training scenes, scored on the validation scenes: the own speed
# (every state) and the leader's gap (the states with a leader in the view), read from all
# twelve planes and from the eight without the past (`ego_t-1`, `ego_t-2`,
# `vehicles_t-1`, `vehicles_t-2`). A few seconds per probe.

# %% tags=["nbval-ignore-output"]
VIEW9 = world.RasterConfig(encoding="channels", route=True, history=2)
learn9 = world.generate(28, seed=1, raster=VIEW9, workers=1)
l_train9, l_val9 = learn9.split(22)
tg9, tgv9 = (diagnose.perception_targets(d, view=VIEW9) for d in (l_train9, l_val9))
col9 = {name: k for k, name in enumerate(tg9.names)}
y_all9, yv_all9 = (t.values.reshape(-1, len(t.names)) for t in (tg9, tgv9))
lead9, leadv9 = y_all9[:, col9["has_leader"]] > 0, yv_all9[:, col9["has_leader"]] > 0
planes9, planesv9 = (np.stack([world.encodings.to_input(d.bev[s], VIEW9) for s in range(len(d))])
                     .reshape(len(d) * d.n_steps, -1, len(VIEW9.channel_names))
                     for d in (l_train9, l_val9))
kept9 = {"all 12 planes": list(range(len(VIEW9.channel_names))),
         "without the past": [k for k, n in enumerate(VIEW9.channel_names) if "t-" not in n]}
r2_9 = {}
try:
    for label, ch in kept9.items():
        Zs = planes9[..., ch].reshape(len(planes9), -1)
        Zvs = planesv9[..., ch].reshape(len(planesv9), -1)
        v9, vv9 = y_all9[:, [col9["v"]]], yv_all9[:, [col9["v"]]]
        g9, gv9 = y_all9[lead9][:, [col9["gap"]]], yv_all9[leadv9][:, [col9["gap"]]]
        r2_9[label] = (probe_r2(Zs, v9, Zvs, vv9, 100.0)[0],
                       probe_r2(Zs[lead9], g9, Zvs[leadv9], gv9, 100.0)[0])
except NotImplementedError:
    print("write probe_r2 (exercise 12.9) to fill this table")
for label, (r2_v, r2_gap) in r2_9.items():
    print(f"{label}: own speed R² {r2_v:.2f}, gap R² {r2_gap:.2f} "
          f"({len(planes9)} training states)")
if r2_9:
    assert r2_9["all 12 planes"][0] > 0.5 > r2_9["without the past"][0] + 0.3
    assert r2_9["all 12 planes"][1] < 0.6

# %% [markdown]
# **Written question (graded by hand, 2 points).** Why does the dual form need `ridge > 0`
# when there are more features than states (what is the rank of `A Aᵀ`)? Read the table:
# why can a *linear* read-out of the pixels give the own speed once the past planes are
# there, and not without them? Why does the gap stay poorly read from the same pixels even
# though the leader's box is drawn in them, and what does that say about what the auxiliary
# loss of tutorial section 7(c) asks of the backbone?

# %% [markdown] answer id=ex12_9_w title="What the pixels hold linearly" points=2
# ### BEGIN SOLUTION
# The standardised features are centred on the training states, so the rows of `A` sum to
# zero and `A Aᵀ` (N × N) has rank at most `N − 1` (and at most `D`): without a penalty the
# `N`-equation system is singular; `ridge · I` makes it positive definite. (The same
# centring is why the intercept is the mean of `y`: its normal equation reads
# `N b = Σ y − (Σ a) w` with `Σ a = 0`.)
#
# The ego's box at t is drawn in the same pixels in every state; its box at t−2 lies behind
# it by the distance driven in 2Δt, so *which* rows of the `ego_t-2` plane are lit is a
# function of the speed, and a weighted sum over those rows (a weight per row ≈ the speed
# that lights it) reads the speed almost linearly: the probe's `R²` is high with the past
# planes and near or below zero without them, where nothing in a single frame tells the
# speed. The gap is not such a sum: it is the distance to the *nearest* box ahead *in the
# ego's lane* — a minimum over the lit pixels after a selection by lane — so where a second
# car is drawn, or a car in the next lane, the same pixels add the wrong evidence; a linear
# read-out of the raw pixels cannot express "the first car ahead in my lane". A backbone
# must compute that from the pixels, which is what the auxiliary loss asks: it trains the
# convolutions to make features from which the gap *is* linear, the very thing the probe of
# section 7(c) measures on the features instead of the pixels.
# ### END SOLUTION

# %% [markdown]
# ## The library's versions at work
# The library's pieces (`bounds.median_style`, `metrics.trajectory.along_cross_track`,
# `P.features`, `world.history.history_of`) are used from here on, so this cell runs even
# while the exercises are open: the style floor of one more validation scene, and the
# expert's perception of one state as the learner reads it.

# %%
style = bounds.median_style(2000)
floor = bounds.floor_rollout(val, style, scenes=[4])
along, cross = along_cross_track(floor.ego, val.ego[[4]])
k = 4 * val.n_steps + 20  # scene 4, step 20 of the validation states
sit = HumanExpert(val).situation(4, 20, val.ego[4, 20], float(Xv[k, 0]))
same = bool(np.allclose(P.features(sit, float(Xv[k, 1])), Xv[k]))
start = float(np.hypot(along[0, 0], cross[0, 0]))
print(f"the expert's features of scene 4, step 20 equal the demonstration's: {same}")
print(f"the floor starts at the human's pose (to 1e-4 m): {start < 1e-4}")
assert same and start < 1e-4

# %% [markdown]
# ## Your figure
# Left: the library's faded history of one frame (`world.history.history_of`) drawn at a
# geometric decay of 0.6; middle: **your** `faded_boxes` at the same decay — the two must
# look alike (a box missing, an ado of the wrong step or a wrong brightness shows).
# Right: **your** ablation table as bars over the library's (dashed), each RMSE as a ratio
# to the learner with every input: a bar above 1 is information the learner uses. A
# function that still raises is named in its panel's title.

# %%
s_fig, t_fig, h_fig = 0, 20, 3
past = world.history.history_of(val.ego[s_fig], val.ado[s_fig], val.ado_valid[s_fig], h_fig,
                                frames=[t_fig])
groups = list(P.FEATURE_GROUPS)
reference = {}
for g in [None, *groups]:
    m_fig = P.fit_privileged(X, Y, drop=[] if g is None else [g], hidden=(16, 16), steps=300,
                             seed=0)
    r_fig = np.sqrt(((P.predict(m_fig, Xv) - Yv) ** 2).mean(axis=0))
    reference["all inputs" if g is None else f"without {g}"] = tuple(float(v) for v in r_fig)
plot_investigation_attempts(
    val.ego[s_fig, t_fig], val.ado[s_fig, t_fig], val.ado_valid[s_fig, t_fig],
    lambda: faded_boxes(val.ego[s_fig], val.ado[s_fig], val.ado_valid[s_fig], t_fig, h_fig, 0.6),
    past, 0.6 ** np.arange(1, h_fig + 1),
    lambda: ablation_table(X, Y, Xv, Yv, groups, 300), reference,
)
plt.show()
