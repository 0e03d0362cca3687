# %% [markdown]
# # Chapter 0 — Overview: what this course builds
#
# This course rebuilds, from first principles, the **Multi-Abstractive Neural
# Controller** (MANC) for interactive driving. Every piece is written by you in
# a notebook and lives, finished, in the small library `minimanc`.
# This chapter builds the course machinery itself: `minimanc.exercises`
# (solutions → exercises, grading) and the `minimanc` command.
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

# %%
import matplotlib.pyplot as plt
from matplotlib.patches import FancyBboxPatch

from minimanc.cli import CHAPTERS


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
# `exercises/` (with its solved twin in `solutions/`), and builds one module of
# the library. Later chapters use the library's reference implementation, so
# being stuck in chapter 4 does not stop you in chapter 5.

# %%
for number, name, what in CHAPTERS:
    print(f"{number}  {name:<17} {what}")

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
