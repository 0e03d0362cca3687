"""Chapter 0 — the chapter map, written once: every chapter's number, notebook, title and modules.

The course has one notebook per chapter, under the same file name in ``tutorials/``,
``solutions/`` and ``exercises/``; chapter N builds the modules :data:`CHAPTERS` gives it.
``minimanc info`` prints this map, tutorial 00 shows it, and the tests check the README's
"## Chapters" table (:func:`markdown_table`), every module's "Chapter N — ..." docstring
(:func:`chapter_of`) and every notebook's first markdown cell against it.

A :class:`Chapter` names its modules in two groups: ``modules``, the chapter's own rooms
(named by its notebooks' first cell and by the README), and ``also``, the modules it builds
that live in another chapter's package or in a shared one (its command, its figures). A
module belongs to the chapter of the longest name among all of them that is the module
itself or one of its parent packages; :data:`SHARED` lists the modules of no chapter.

Each chapter also carries what a student starts from: its objectives, prerequisites and
time estimate, whose text (:meth:`Chapter.opening`) ends its tutorial's first cell.
"""

from __future__ import annotations

import textwrap
from dataclasses import dataclass

__all__ = ["CHAPTERS", "SHARED", "Chapter", "chapter_of", "markdown_table"]


@dataclass(frozen=True)
class Chapter:
    """One chapter of the course.

    Attributes
    ----------
    number : int
        The chapter's number, 0–12.
    notebook : str
        The notebooks' file name without ``.ipynb``, e.g. ``"03_dmp"``.
    title : str
        What the chapter builds, in a few words.
    modules : tuple of str
        The chapter's own modules (packages), named by its notebooks' first cell.
    also : tuple of str
        Further modules the chapter builds that live elsewhere in the tree.
    exercises : str
        The subject of the chapter's graded set.
    objectives : tuple of str
        What a student can do after the chapter (each completes "you can ...").
    prerequisites : str
        What to know (and which chapters to have done) before starting it.
    minutes : tuple of (int, int)
        The time estimate in minutes: the tutorial, then the exercises.
    """

    number: int
    notebook: str
    title: str
    modules: tuple[str, ...]
    also: tuple[str, ...]
    exercises: str
    objectives: tuple[str, ...]
    prerequisites: str
    minutes: tuple[int, int]

    @property
    def code(self) -> str:
        """The two-digit number that starts the notebook's name, e.g. ``"03"``."""
        return f"{self.number:02d}"

    @property
    def name(self) -> str:
        """The notebook's name without its number, e.g. ``"dmp"``."""
        return self.notebook.split("_", 1)[1]

    @property
    def shown(self) -> tuple[str, ...]:
        """The modules the chapter map shows for it: its own, or, for a chapter that has no
        package of its own, the modules it builds elsewhere (``also``)."""
        return self.modules or self.also

    def opening(self) -> str:
        """The objectives, prerequisites and time estimate that end the tutorial's first cell.

        Returns
        -------
        str
            Markdown: an "Objectives" list, a "Prerequisites" line and a "Time" line.
        """
        items = "\n".join(textwrap.fill(o, 90, initial_indent="- ", subsequent_indent="  ")
                          for o in self.objectives)
        tutorial, exercises = self.minutes
        return (f"**Objectives.** After this chapter you can\n{items}\n\n"
                + textwrap.fill(f"**Prerequisites.** {self.prerequisites}", 90) + "\n\n"
                f"**Time.** About {tutorial} minutes for the tutorial and {exercises} "
                "for the exercises.")


CHAPTERS: tuple[Chapter, ...] = (
    Chapter(0, "00_overview", "the stack, the chapter map, grading",
            ("minimanc.exercises", "minimanc.cli"),
            ("minimanc.chapters", "minimanc.viz.exercises"),
            "warm-up tools of later chapters: an ego-frame transform (ch. 7), "
            "a column softmax (ch. 5), an explicit Euler step (ch. 3)",
            objectives=(
                "describe the MANC stack (CNN predicates → vAGN automaton → DMP) and the "
                "chapter that builds each piece",
                "work an exercises notebook and grade it with `minimanc grade`",
            ),
            prerequisites="Python and NumPy basics; no earlier chapter.",
            minutes=(15, 15)),
    Chapter(1, "01_autodiff", "reverse-mode autodiff on NumPy",
            ("minimanc.autodiff", "minimanc.engine"), ("minimanc.tree", "minimanc.viz.graph"),
            "unbroadcasting, VJPs, the tape's topological order, grad, the computation graph",
            objectives=(
                "derive and write vector-Jacobian products, also across broadcasting",
                "build reverse-mode `grad` from a tape and its topological order",
                "check any gradient against central differences",
            ),
            prerequisites="Chapter 0; NumPy broadcasting; the chain rule.",
            minutes=(60, 120)),
    Chapter(2, "02_training", "layers, conv2d, Adam",
            ("minimanc.layers", "minimanc.optim", "minimanc.autodiff.nn"), (),
            "convolution, pooling, initialisation and optimisers",
            objectives=(
                "write a convolution's forward and backward passes (by loops and by im2col)",
                "initialise layers so that the signal survives depth (He, Glorot)",
                "implement SGD, momentum and Adam on pytrees and train a small CNN",
            ),
            prerequisites=(
                "Chapter 1 (VJPs, `grad`); matrix products; what a loss and a "
                "gradient step are."
            ),
            minutes=(60, 150)),
    Chapter(3, "03_dmp", "point-attractor DMP, damping ratio, stability",
            ("minimanc.dmp",), (),
            "DMP damping, step stability, forcing term",
            objectives=(
                "read the damping ratio and the convergence of the DMP's point attractor (eqs. "
                "10–13)",
                "decide when a discrete integrator step is stable (its spectral radius) and "
                "bound the gains",
                "fit a forcing term by locally weighted regression",
            ),
            prerequisites=(
                "Chapter 1; linear second-order ODEs and the eigenvalues of a 2×2 "
                "matrix."
            ),
            minutes=(60, 150)),
    Chapter(4, "04_quaternions", "quaternion log/exp and DMP",
            ("minimanc.quaternion",), (),
            "quaternion product, log, exp, orientation error, integration, a turning goal",
            objectives=(
                "compute quaternion products, log and exp maps (eqs. 3–6) and orientation "
                "errors",
                "integrate the quaternion DMP (eq. 2) and avoid its traps (two quaternions per "
                "rotation, the log at −1, NaN gradients)",
            ),
            prerequisites="Chapter 3 (the point-attractor DMP); rotations in 3-D.",
            minutes=(60, 120)),
    Chapter(5, "05_vagn", "the soft automaton",
            ("minimanc.vagn",), ("minimanc.viz.automaton",),
            "the vAGN soft automaton, learning it from the DMP's actions alone",
            objectives=(
                "build the vAGN transition matrix from predicates (eqs. 8–9) and step the soft "
                "automaton",
                "train it by gradient descent and read its q-states",
            ),
            prerequisites=(
                "Chapter 2 (softmax, training); Markov chains and column-stochastic "
                "matrices."
            ),
            minutes=(60, 120)),
    Chapter(6, "06_cam", "visual predicates and CAM saliency",
            ("minimanc.cam",), ("minimanc.viz.saliency",),
            "class activation maps, Grad-CAM, baselines, q-state saliency, a ReLU head",
            objectives=(
                "compute visual predicates with conv → global average pooling → linear (eq. 7)",
                "split a predicate into a class activation map and compare it with Grad-CAM "
                "and baselines",
            ),
            prerequisites=(
                "Chapter 2 (convolution, global average pooling); chapter 5 for what "
                "the predicates drive."
            ),
            minutes=(45, 90)),
    Chapter(7, "07_world", "nuScenes-style BEV world and data",
            ("minimanc.world",), ("minimanc.viz.world", "minimanc.cli.data"),
            "frames, the BEV raster, the IDM, the lane-following expert",
            objectives=(
                "convert between world and ego frames and step the unicycle at Δt = 0.5 s",
                "generate maps, IDM traffic and a styled human driver",
                "rasterise the bird's-eye view and build a split dataset",
            ),
            prerequisites="Chapter 0; plane geometry (frames, headings).",
            minutes=(45, 90)),
    Chapter(8, "08_manc", "the assembled controller",
            ("minimanc.models", "minimanc.inputs", "minimanc.train"), (),
            "assembling MANC",
            objectives=(
                "assemble MANC and its rival models as pure functions (the paper's Figure 1)",
                "train them by behaviour cloning (Algorithm 1) on both engines",
            ),
            prerequisites="Chapters 2–7.",
            minutes=(60, 90)),
    Chapter(9, "09_behavior_cloning", "training, closed loop, the paper's studies",
            ("minimanc.rollout", "minimanc.metrics", "minimanc.studies"),
            ("minimanc.viz.study", "minimanc.viz.explain", "minimanc.cli.reproduce",
             "minimanc.cli.results"),
            "the MANC step, the closed loop, a metric",
            objectives=(
                "drive a learned controller in closed loop and measure it like Table I",
                "explain the information-parity lesson and test whether MANC's q-states are "
                "driving modes",
            ),
            prerequisites="Chapter 8 (the models, behaviour cloning).",
            minutes=(60, 90)),
    Chapter(10, "10_highway_sandbox", "the controller in highway-env",
            ("minimanc.highway",), ("minimanc.cli.highway", "minimanc.viz.highway"),
            "the controller in a real driving simulator; what the logs record in a turn; a "
            "driver that yields",
            objectives=(
                "run the same controller in highway-env, among traffic that reacts",
                "collect expert demonstrations and measure collisions, leaving the road and "
                "ADE",
            ),
            prerequisites=(
                "Chapter 9 (policies, the closed loop); the optional highway-env "
                "install."
            ),
            minutes=(40, 60)),
    Chapter(11, "11_dagger", "behaviour cloning's drift and DAgger",
            ("minimanc.dagger",),
            ("minimanc.studies.dagger_study", "minimanc.viz.dagger", "minimanc.cli.dagger"),
            "the DAgger schedule, the mixture, aggregation, the budget; the cost of "
            "compounding; BC against DAgger for a linear learner",
            objectives=(
                "explain why behaviour cloning drifts in closed loop",
                "run DAgger's rounds with a β-mixture and a label budget, and compare at an "
                "equal budget",
            ),
            prerequisites="Chapter 9 (behaviour cloning, the closed-loop metrics).",
            minutes=(45, 60)),
    Chapter(12, "12_why_it_crashes", "why the driver crashes",
            ("minimanc.diagnose",), ("minimanc.viz.investigation",),
            "the median style and the track errors, the expert's perception, an ablation "
            "table, faded history at another decay, a small input set, a masked loss and its "
            "gradient, the history planes, the view's reach",
            objectives=(
                "read a learned driver's ADE and at-fault rate against the expert and the style "
                "floor",
                "separate a failure of learning from a lack of information with a privileged "
                "learner and an ablation of its inputs",
                "classify a driver's collisions and draw the motion a single raster frame lacks "
                "as faded history",
                "draw a raster for learning and train a perception on targets that say "
                "\"no leader\"",
            ),
            prerequisites=(
                "Chapters 9 and 11 (the closed loop, its metrics, the world's expert); "
                "chapter 7 for the world's human driver and the raster."
            ),
            minutes=(60, 120)),
)
"""Every chapter, in order."""

SHARED: tuple[str, ...] = (
    "minimanc",
    "minimanc.__main__",
    "minimanc.checks",
    "minimanc.errors",
    "minimanc.viz",
    "minimanc.viz.style",
)
"""Modules of no single chapter: the package, its entry point, what every chapter shares."""


def chapter_of(module: str) -> Chapter | None:
    """The chapter that builds ``module``, or ``None`` for a module of no chapter.

    Parameters
    ----------
    module : str
        A dotted module name, e.g. ``"minimanc.dmp.flow"``.

    Returns
    -------
    Chapter or None
        The chapter of the longest name in its ``modules`` or ``also`` that is ``module``
        itself or one of its parent packages; ``None`` when there is none.
    """
    best: tuple[int, Chapter] | None = None
    for chapter in CHAPTERS:
        for owned in chapter.modules + chapter.also:
            if module == owned or module.startswith(owned + "."):
                if best is None or len(owned) > best[0]:
                    best = (len(owned), chapter)
    return None if best is None else best[1]


def markdown_table() -> str:
    """The README's "## Chapters" table: number, notebook, what it builds and its modules.

    Returns
    -------
    str
        The table's lines (header, rule, one row per chapter), each ending in a newline.
    """
    lines = ["| # | notebook | builds |", "|---|---|---|"]
    for chapter in CHAPTERS:
        modules = ", ".join(f"`{m}`" for m in chapter.shown)
        lines.append(f"| {chapter.code} | `{chapter.notebook}` | {chapter.title} — {modules} |")
    return "".join(line + "\n" for line in lines)
