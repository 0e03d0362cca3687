# %% [markdown]
# # Chapter 12 — Why the driver crashes
#
# Modules built in this chapter: `minimanc.diagnose` — its `bounds` (the expert and the style
# floor), `privileged` and `policies` (a learner given what the expert perceives, driving),
# `probe` and `collisions` — and `minimanc.viz.investigation` (the chapter's figures); it
# puts to work `minimanc.world.history` (faded history in the raster) and
# `minimanc.metrics.safety` (the collision taxonomy).
#
# Every behaviour-cloned controller of chapters 9–11 collides in a sizeable share of the
# validation scenes, also among ados that react to it, where the human whose logs it copies
# never does. This chapter walks through the investigation that finds out why, with the
# library's own parts, on a course-sized world (`research/why_it_crashes/REPORT.md` records
# the same measurements at the paper's size, and the investigation's further experiments):
#
# | question | the library's answer |
# |---|---|
# | the best any learner can do? | `bounds.expert_rollout`, `bounds.floor_rollout` |
# | learning or information? | `P.fit_privileged`, `PrivilegedPolicy` (what the expert sees) |
# | which information? | `P.fit_privileged(..., drop=[group])`: the ablation |
# | how does it crash? | `metrics.safety.collision_events`: the taxonomy |
# | can the image carry it? | `world.RasterConfig(history=H)`, `world.history` |
#
# **Objectives.** After this chapter you can
# - read a learned driver's ADE and at-fault rate against the expert and the style floor
# - separate a failure of learning from a lack of information with a privileged learner and
#   an ablation of its inputs
# - classify a driver's collisions and draw the motion a single raster frame lacks as faded
#   history
#
# **Prerequisites.** Chapters 9 and 11 (the closed loop, its metrics, the world's expert);
# chapter 7 for the world's human driver and the raster.
#
# **Time.** About 45 minutes for the tutorial and 90 for the exercises.

# %%
from collections import Counter

import matplotlib.pyplot as plt
import numpy as np

from minimanc import metrics, rollout, world
from minimanc.dagger.teachers import WorldTeacher
from minimanc.diagnose import PrivilegedPolicy, bounds
from minimanc.diagnose import privileged as P
from minimanc.metrics.safety import collision_events
from minimanc.metrics.trajectory import ade, along_cross_track
from minimanc.viz.investigation import plot_history_boxes

np.set_printoptions(precision=2, suppress=True)

# %% [markdown]
# ## 1. Data
# 48 scenes of the chapter-7 world: 40 for training (their demonstrations), 8 to drive on.
# The raster is small (16 px): nothing in this chapter but section 6 reads it.

# %%
data = world.generate(48, seed=0, raster=world.RasterConfig(size=16), workers=1)
train, val = data.split(40)
T = val.n_steps
print(f"{len(train)} training scenes, {len(val)} validation scenes, {T} steps of {val.dt} s")
assert (len(train), len(val), T) == (40, 8, 40)

# %% [markdown]
# ## 2. The bounds every number is read against
# **The expert.** The world's own human driver (`minimanc.dagger.expert.HumanExpert`),
# asked in every state the closed loop reaches (`policies.ExpertPolicy`), drives through
# the same time loop and the same simulator as every learned policy (`bounds.expert_rollout`
# takes the protocol as `agents=` and returns a `rollout.Rollout`, as `rollout.simulate`
# does, with the states the expert could not be asked in as `refused`). Here the ados react
# to the ego (`agents="reactive"`, chapter 9's second protocol). If the pipeline is sound
# (labels paired with the right step, no unit slip, the expert asked in the state the
# policy reached) it reproduces the log: no distance to the human, no collision.
#
# Closed-loop numbers pass through a chaotic simulation (a yield at a junction decided
# one step earlier changes the rest of a scene), so cells that print them carry the tag
# `nbval-ignore-output` and check what they show with an `assert`.

# %% tags=["nbval-ignore-output"]
expert_traj = bounds.expert_rollout(val, agents="reactive")
expert = metrics.evaluate(expert_traj, val)
print(f"expert: ADE {expert['ade']:.2f} m, at fault {expert['at_fault_collision_rate']:.1f} %, "
      f"off road {expert['off_road_rate']:.1f} %, refused {expert_traj.refused}")
assert expert["ade"] < 1e-3 and expert["at_fault_collision_rate"] == 0
assert expert_traj.refused == 0

# %% [markdown]
# **The style floor.** Each scene's human draws a hidden *style*
# (`world.driver.random_style`: desired speed $v_0$, time headway $T$, comfortable
# acceleration and braking, reaction delay, ...) that nothing in the scene shows. The
# floor re-drives every scene with the same driver on the scene's own map, traffic and
# noise, its style replaced by the population's field-wise median (`bounds.median_style`),
# the ados reacting to it. Its distance to the logged human is what a driver that sees the
# road and the traffic perfectly, but not the style, still makes. Re-driven with its own
# style (`style=None`), a scene reproduces its log: that is the check of the floor itself.

# %% tags=["nbval-ignore-output"]
style = bounds.median_style()
print(f"median style: v0 {style.v0:.2f} m/s, T {style.T:.2f} s, reaction {style.reaction:.2f} s")
own = bounds.floor_rollout(val, None, scenes=[0, 1])
print(f"own style re-drives the log to 1e-3 m: {np.abs(own.ego - val.ego[:2]).max() < 1e-3}")
floor = bounds.floor_rollout(val, style)
floor_ade = ade(floor.ego, val.ego)
along, cross = along_cross_track(floor.ego, val.ego)
print("style floor ADE per scene (m):", floor_ade)
print(f"mean {floor_ade.mean():.2f} m: along the road {np.abs(along).mean():.2f} m, "
      f"across it {np.abs(cross).mean():.2f} m")
assert np.abs(own.ego - val.ego[:2]).max() < 1e-3
assert 0 < floor_ade.mean() < 20 and np.abs(along).mean() > np.abs(cross).mean()

# %% [markdown]
# Almost all of the floor's error is *along* the road: a driver of another style keeps the
# lane like the human but drives it at another speed. `research/why_it_crashes/REPORT.md` (its
# section on the bounds) reports the same at the paper's size (200 scenes): the expert at
# zero, the floor a few metres, its along-track part nearly all of it, and no at-fault
# collision of the median-style driver. The learned image models of Table I trail the human by
# more than twice the floor's ADE and collide where the floor never does: hidden style does
# not explain them.

# %% [markdown]
# ## 3. The privileged learner: is it the learning or the information?
# A learner given exactly the numbers the expert perceives (Chen et al. 2019,
# *Learning by Cheating*) separates the two causes. If it drives like the expert, behaviour
# cloning, the labels and the closed loop work, and what the image models lack is
# information. `HumanExpert.situation` puts the ego at a pose and speed among the step's
# ados and returns what the human perceives there; `privileged.features` turns it into 13
# numbers, in groups:

# %%
for group, names in P.FEATURE_GROUPS.items():
    print(f"{group:8s} {', '.join(names)}")
assert len(P.FEATURES) == 13

# %% [markdown]
# The demonstrations are every logged state of the training scenes: its features and the
# human's logged controls there as `[acceleration, yaw rate]`. One state, with a leader:

# %% tags=["nbval-ignore-output"]
X, Y = P.demonstrations(train)
Xv, Yv = P.demonstrations(val)
print("demonstrations", X.shape, Y.shape, "validation states", Xv.shape)
k = int(np.argmax(X[:, P.FEATURES.index("has_leader")]))
print({name: round(float(x), 2) for name, x in zip(P.FEATURES, X[k])})
assert X.shape == (40 * T, 13) and Xv.shape == (8 * T, 13)
assert X[k, P.FEATURES.index("gap")] < P.FAR and np.all(np.isfinite(X))

# %% [markdown]
# An MLP (two tanh layers of 32) on the standardised features predicts both controls; it
# is trained by Algorithm 1 (`P.fit_privileged`: minibatches, mean squared error of each output
# divided by its spread, Adam, cosine decay) and drives closed loop through
# `PrivilegedPolicy`, which asks the expert for its perception in every state it
# reaches and applies $[\mathrm{clip}(v + a\,\Delta t, 0, V_{max}), \omega]$. A course-sized
# run (1500 steps on 1600 states): read its numbers against the bounds above.

# %% tags=["nbval-ignore-output"]
STEPS, HIDDEN = 1500, (32, 32)


def drive(model):
    """The closed-loop rollout of a privileged learner on the validation scenes."""
    policy = PrivilegedPolicy(model, WorldTeacher(val, agents="reactive"))
    return rollout.simulate(policy, val, agents="reactive", progress=False)


full = P.fit_privileged(X, Y, hidden=HIDDEN, steps=STEPS, seed=0)
full_traj = drive(full)
full_m = metrics.evaluate(full_traj, val)
rmse = np.sqrt(((P.predict(full, Xv) - Yv) ** 2).mean(0))
print(f"open loop RMSE: acceleration {rmse[0]:.2f} m/s² (spread {Yv[:, 0].std():.2f}), "
      f"yaw rate {rmse[1]:.3f} rad/s (spread {Yv[:, 1].std():.3f})")
print(f"closed loop: ADE {full_m['ade']:.2f} m ({full_m['ade'] / floor_ade.mean():.1f}x the "
      f"floor), at fault {full_m['at_fault_collision_rate']:.1f} %")
assert full.losses[-1] < full.losses[0] and np.all(rmse < Yv.std(0))
assert np.isfinite(full_m["ade"]) and full_m["ade"] < 8 * floor_ade.mean()

# %% [markdown]
# Forty demonstrations (1600 states) are few for this learner: read its ADE against the
# floor's and its at-fault rate against the expert's zero, both printed above, and know that
# another training seed moves both numbers a lot (try `seed=1`).
# `research/why_it_crashes/REPORT.md` measures the same learner at the
# paper's size (650 training scenes, 200 validation scenes, 3 seeds): at the style floor's ADE
# and within a few points of the expert's collision rate, where the image models of Table I
# collide several times as often. Given the expert's information and enough data, behaviour
# cloning works; what the image models lack is information.

# %% [markdown]
# ## 4. Which information? The ablation
# `P.fit_privileged(..., drop=[group])` trains the same learner without one group of inputs. Each
# ablated learner drives the same scenes; the one whose removal costs most is the
# information that matters. Two groups here (each fit and drive takes a few seconds);
# the exercises build the whole table.

# %% tags=["nbval-ignore-output"]
trajs = {"all inputs": full_traj}
for group in ("leader", "lane"):
    trajs[f"without {group}"] = drive(P.fit_privileged(X, Y, drop=[group], hidden=HIDDEN,
                                                       steps=STEPS))
table = {name: metrics.evaluate(traj, val) for name, traj in trajs.items()}
print("| inputs | ADE m | at fault % | off road % |\n|---|---|---|---|")
for name, m in table.items():
    print(f"| {name} | {m['ade']:.2f} | {m['at_fault_collision_rate']:.1f} | "
          f"{m['off_road_rate']:.1f} |")
assert table["without lane"]["ade"] > table["all inputs"]["ade"], "the lane steers it"

# %% [markdown]
# At the paper's size (`research/why_it_crashes/REPORT.md`, "Ablation"): without the `leader`
# group (the gap and the speed difference to the vehicle ahead) the learner runs into the
# vehicle ahead about as often as the image models; without `history` (its last acceleration)
# it does *better* — the copycat of causal confusion (de Haan et al. 2019): a learner that
# sees its last control learns to repeat it. And given only what one raster frame can show —
# positions, but neither its own speed nor the closing speed — it falls to the image models'
# level ("What one image can show").

# %% [markdown]
# The same learner can also be made to drive through MANC's own parts, to ask which of them
# keeps MANC from driving (the investigation's own code, `research/why_it_crashes/heads.py`,
# not the library's): the MLP predicts the four gain logits of eq. 11 and drives through
# MANC's DMP head; or it predicts MANC's predicates, followed by vAGN, `FC(q)` and the head,
# trained on whole scenes; or the gains read the predicates beside q. At the paper's size
# (`research/why_it_crashes/REPORT.md`, "MANC's pieces on the expert's perception") the DMP
# head drives as well as the plain output, the automaton with `FC(q)` drives well for some
# training seeds and at the image models' level for others, and with `FC(q ⊕ p)` every seed
# drives: each part of MANC works when it perceives what the expert perceives, so what MANC
# lacks is in its predicates, its perception of the leader.

# %% [markdown]
# ## 5. How does it crash? The collision taxonomy
# `metrics.safety.collision_events` finds every ego–ado contact (each ado once, at its
# first contact) and classifies it as nuPlan does: `stopped_ego` (not at fault),
# `stopped_ado`, `rear` (the ado came from behind: not at fault), `front` (the ego's
# front edge hit it) and `lateral` (at fault when the ego was not inside a lane). A
# driver that does not see its leader should rear-end it: `front` and `stopped_ado`.
# At each contact we compare the speed the driver applied with the human's at the same
# step of the log.

# %% tags=["nbval-ignore-output"]
kinds = {}
for name, traj in trajs.items():
    events = collision_events(traj.ego, traj.ado, traj.ado_valid, maps=val.maps)
    kinds[name] = Counter(e.kind for e in events)
    faster = [traj.controls[e.scene, max(e.step - 1, 0), 0]
              - val.controls[e.scene, max(e.step - 1, 0), 0] for e in events if e.at_fault]
    extra = f", {np.mean(faster):+.1f} m/s against the human" if faster else ""
    print(f"{name:16s} {dict(kinds[name])} at fault: {sum(e.at_fault for e in events)}{extra}")
    for e in events:
        assert e.at_fault == (e.kind in ("front", "stopped_ado")
                              or (e.kind == "lateral" and not e.in_lane))

# %% [markdown]
# The issue that started this investigation made the same table for the paper's MANC and
# CNN (100 fresh scenes): nearly every collision is `front` or `stopped_ado`, and at
# contact the learned driver is faster than the human was at the same step. The learned
# drivers do not slow down for what is ahead of them — the information the `leader` group
# carries, and one raster frame does not.

# %% [markdown]
# ## 6. Can the image carry it? Faded history
# One raster frame shows where the leader is, not how fast it or the ego moves. The nuScenes
# devkit's prediction raster draws each agent's last seconds as boxes of decreasing
# brightness (`AgentBoxesWithFadedHistory`). `world.RasterConfig(history=H)` draws, under
# the current boxes, those of the $H$ previous steps, the ego's too, each scaled by
# `world.history.fade`: $1 - j/(H+1)$ for the box $j$ steps ago.

# %%
for H in (1, 2, 4):
    print(f"H = {H}: brightness of the boxes 1..{H} steps ago", world.history.fade(H))
assert np.allclose(world.history.fade(2), [2 / 3, 1 / 3])

# %% [markdown]
# `world.history.history_of` collects a track's past boxes for the frames to draw (the log
# when a dataset is written, the closed loop's own record when it drives), and
# `world.rasterize` draws them. The same frame without and with two steps of history, and
# the boxes themselves in the ego frame (`minimanc.viz.investigation.plot_history_boxes`):

# %%
scene, t, H = 0, 20, 2
past = world.history.history_of(val.ego[scene], val.ado[scene], val.ado_valid[scene], H,
                                frames=[t])
print("past ego poses", past.ego.shape, "past ado boxes", past.ado.shape)
frames = [world.rasterize(val.maps[scene], val.ego[scene, t], val.ado[scene, t],
                          val.ado_valid[scene, t], world.RasterConfig(history=h),
                          history=past if h else None) for h in (0, H)]
print("raster", frames[1].shape, frames[1].dtype)
fig, axes = plt.subplots(1, 3, figsize=(12, 4))
for ax, img, h in zip(axes, frames, (0, H)):
    ax.imshow(img, origin="upper")
    ax.set(title=f"history = {h}", xticks=[], yticks=[])
plot_history_boxes(val.ego[scene, t], val.ado[scene, t], val.ado_valid[scene, t], past,
                   world.history.fade(H), ax=axes[2])
plt.tight_layout()
plt.show()
assert past.ego.shape == (1, H, 3) and frames[1].shape == (64, 64, 3)
assert past.ego_valid.all(), "step 20 has two past steps"

# %% [markdown]
# The gap between the ego's current and past boxes is its speed times $\Delta t$; the change
# of the gap to the leader between the frames is the closing speed. Measured for the CNN over
# three seeds (`research/why_it_crashes/REPORT.md`), faded history lowers its at-fault rate by
# a little more than the seed spread and leaves it far above the privileged learner's: the
# information is now in the image, but a convolutional reading of two faded boxes does not yet
# recover it to the precision a speed command needs (the report's modular learner and its "A
# perception that errs": an error of half a metre per second in its own speed costs the
# privileged learner more than losing its leader).

# %% [markdown]
# ## Paper vs. this course
# The paper reports open-loop imitation and close encounters; it has no expert to ask, no
# style floor and no privileged learner, because a logged human can be neither re-driven
# with another style nor asked in a state it never visited. Our world's human is a model
# (chapter 7), so both bounds and the privileged learner are exact here, and the
# investigation can say which information a controller lacks instead of guessing. What it
# cannot say is how a real driver's hidden style compares with ours: the style floor is a
# property of this world's population of styles.
