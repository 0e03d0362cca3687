# %% [markdown]
# # Chapter 0 — Overview: what this course builds
#
# This course rebuilds, from first principles, the **Multi-Abstractive Neural
# Controller** (MANC) for interactive driving. Every piece is written by you in
# a notebook and lives, finished, in the small library `minimanc`.
# This chapter builds the course machinery itself: `minimanc.exercises`
# (solutions → exercises, grading) and the `minimanc` command (`minimanc.cli`).
#
# ## The driving stack
# A classical autonomy stack splits driving into a **behaviour planner** (what
# to do: follow, yield, turn), a **motion controller** (how to move there) and
# the **controls** sent to the vehicle. MANC keeps this split but makes every
# layer differentiable, so the whole stack is learned from human driving:
#
# * a CNN **visual predicate extractor** reads a bird's-eye-view (BEV) image
#   and outputs predicates $p^v$ (eq. 7);
# * the **vAGN**, a soft automaton, turns the predicates into a distribution
#   $q_t$ over abstract behaviour states (eqs. 8–9) — the behaviour planner;
# * a fully connected layer maps $q_t$ to the gains $\alpha, \beta$ of a
#   **DMP**, a stable point attractor towards the goal (eqs. 1–2, 10–11) —
#   the motion controller;
# * integrating the DMP once gives the controls: speed and yaw rate.
#
# **Objectives.** After this chapter you can
# - describe the MANC stack (CNN predicates → vAGN automaton → DMP) and the chapter that
#   builds each piece
# - work an exercises notebook and grade it with `minimanc grade`
#
# **Prerequisites.** Python and NumPy basics; no earlier chapter.
#
# **Time.** About 15 minutes for the tutorial and 15 for the exercises.

# %%
import matplotlib.pyplot as plt
from matplotlib.patches import FancyBboxPatch

from minimanc.chapters import CHAPTERS


def draw_chain(ax, labels, colours, y, title):
    """Boxes joined by arrows, left to right."""
    xs = [1.5 + 2.6 * i for i in range(len(labels))]
    for x, label, colour in zip(xs, labels, colours):
        ax.add_patch(FancyBboxPatch((x - 1.0, y - 0.45), 2.0, 0.9,
                                    boxstyle="round,pad=0.08", fc=colour, ec="black"))
        ax.text(x, y, label, ha="center", va="center", fontsize=9)
    for a, b in zip(xs[:-1], xs[1:]):
        ax.annotate("", xy=(b - 1.08, y), xytext=(a + 1.08, y),
                    arrowprops=dict(arrowstyle="->", lw=1.5))
    ax.text(0.3, y + 0.75, title, fontsize=10, weight="bold")
    return xs


fig, ax = plt.subplots(figsize=(11, 3.6))
draw_chain(ax, ["perception", "behaviour\nplanner", "motion\ncontroller", "controls"],
           ["#dddddd", "#ffe9a8", "#bfe3ff", "#d7f5d0"], 2.3, "A classical driving stack")
draw_chain(ax, ["BEV image", "CNN\npredicates $p^v$", "vAGN\nstates $q_t$",
                "FC\ngains $\\alpha,\\beta$", "DMP\n(speed, yaw rate)"],
           ["#dddddd", "#ffe9a8", "#ffe9a8", "#bfe3ff", "#d7f5d0"], 0.6,
           "MANC: every block differentiable, trained by behaviour cloning")
ax.set_xlim(0, 13.5)
ax.set_ylim(-0.1, 3.4)
ax.axis("off")
plt.show()

# %% [markdown]
# ## The chapter map
# Each chapter has a narrative notebook in `tutorials/`, a graded set in
# `exercises/` (with its solved twin in `solutions/`), and builds its modules of
# the library. The map is data, `minimanc.chapters` (`minimanc info` prints it
# too). Later chapters use the library's reference implementation, so being
# stuck in chapter 4 does not stop you in chapter 5.

# %%
for chapter in CHAPTERS:
    print(f"{chapter.code}  {chapter.name:<17} {chapter.title} — {', '.join(chapter.shown)}")

# %% [markdown]
# ## Working through the exercises
# 1. Open `exercises/NN_name.ipynb` with `jupyter lab` (install the `lab`
#    extra: `pip install -e '.[lab]'`).
# 2. Each exercise cell raises `NotImplementedError("Exercise exNN_K: …")`:
#    replace that line by your code.
# 3. The cell after it (a *grade cell*) checks your work with asserts. The
#    instructor's copy holds extra hidden tests.
# 4. Grade yourself from a terminal:
#
#    ```
#    minimanc grade exercises/00_overview.ipynb
#    ```
#
#    which runs the notebook with the full (hidden) tests and prints the points
#    per exercise. `--json` gives a machine-readable report.
#
# Instructors edit only `solutions/`; `minimanc exercises build` regenerates
# `exercises/`, and `minimanc exercises build --check` (run by the tests) fails
# when they drift apart. The markers follow nbgrader's conventions, so the
# notebooks also work with nbgrader.
#
# ## How grading works, in one example
# The grader turns each solution region into a stub, so the exercise notebook
# fails its tests until the student fills it in:

# %%
from minimanc import exercises

source = '''def double(x):
    ### BEGIN SOLUTION
    return 2 * x
    ### END SOLUTION'''
stub, top_level = exercises.stub_solution(source, "ex00_0", "Double a number", "demo")
print(stub)
assert "NotImplementedError" in stub and not top_level

# %% [markdown]
# ## Paper vs. this course
# The course follows the paper (`manc.tex`: the DMP background of section III,
# the controller of section IV and Algorithm 1) equation by equation, but not
# blindly. The map of where it departs, or where the paper itself slips, and
# why; each chapter's own box has the details:
#
# * **Eq. 1, the canonical system** is printed τẋ = α_x x; the phase must
#   decay, so it reads τẋ = −α_x x (chapter 3). Chapter 3 also builds the
#   forcing term the paper then drops, to show why it must fade.
# * **Numbering slips around eq. 2.** The quaternion DMP is introduced as "the
#   equivalent of Equations (1) and (2)", but it *is* eq. 2; and "Equation (4)
#   can be integrated as" eq. 5 means eq. 2 (its τq̇ = ½ η ∗ q), since eq. 4
#   is the logarithmic map (chapter 4).
# * **Eq. 8 sums over i ∈ {0, M−1}**, a two-element set; it means
#   i = 0, …, M−1 (chapter 5).
# * **Eq. 9's ReLU keeps every transition.** The paper applies the ReLU "to
#   preserve only the positive transitions", but a zero still becomes e⁰ = 1
#   inside the column softmax: no transition ever has probability zero
#   (chapter 5).
# * **Our predicates pass through a sigmoid after eq. 7** (`Linear` in the
#   paper): linear predicates grew in training until eq. 9's softmax
#   saturated and q stopped depending on the image (chapters 6 and 8).
# * **FC(q) = {α_y, β_y, α_y, β_y}** after eq. 11 repeats the position gains;
#   it should end in α_q, β_q, the orientation gains of eq. 10's second row
#   (chapter 8).
# * **The advice to keep α and β from getting "too close together" is
#   backwards.** With eq. 13, ζ = α / (2√(αβ)) = ½√(α/β): α = β gives ζ = ½,
#   and ζ → 0 needs β ≫ α (chapter 3).
# * **Positive gains are not enough.** The paper argues stability from ζ > 0
#   (sigmoid outputs); that holds for the continuous system, but the step of
#   0.5 s can diverge (α = 25, β = α/4: the explicit Euler step matrix has
#   spectral radius 5.25 — a Jordan block with the double eigenvalue −5.25, so
#   the error grows like k·5.25ᵏ after k steps). The course confines the gains to
#   a box in which its integrator is stable (chapter 3).
# * **The goals of eq. 10** are "a moving target along the center lane"
#   without a rule; ours are a lane point 4 m + 2 s · v₀ ahead and the
#   pure-pursuit heading, and the control is the mean velocity over one DMP
#   step (chapter 8).
# * **Our DMP windows span whole scenes** rather than Algorithm 1's single
#   steps: the DMP models train on 40-step windows in which q and the DMP's
#   velocity carry over, because trained step by step the speed drifted in
#   closed loop (chapters 8 and 9); we use Adam instead of the plain gradient
#   step.
# * **Information parity.** The comparison models get the BEV and the goal
#   pose, MANC the lane target; a second setting gives every model the lane
#   target and the motion, so a gap left is the architecture's (chapters 8–9).
# * **Data and sandbox.** nuScenes (850 scenes of 20 s at 2 Hz) cannot ship
#   with a course; chapter 7 builds a nuScenes-style BEV world with the same
#   20 s at 2 Hz, and chapter 10 adds a highway-env sandbox the paper does not
#   have.
