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
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["CHAPTERS", "SHARED", "Chapter", "chapter_of", "markdown_table"]


@dataclass(frozen=True)
class Chapter:
    """One chapter of the course.

    Attributes
    ----------
    number : int
        The chapter's number, 0–11.
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
    """

    number: int
    notebook: str
    title: str
    modules: tuple[str, ...]
    also: tuple[str, ...]
    exercises: str

    @property
    def code(self) -> str:
        """The two-digit number that starts the notebook's name, e.g. ``"03"``."""
        return f"{self.number:02d}"

    @property
    def name(self) -> str:
        """The notebook's name without its number, e.g. ``"dmp"``."""
        return self.notebook.split("_", 1)[1]


CHAPTERS: tuple[Chapter, ...] = (
    Chapter(0, "00_overview", "the stack, the chapter map, grading",
            ("minimanc.exercises", "minimanc.cli"), ("minimanc.chapters",),
            "warm-up tools of later chapters: an ego-frame transform (ch. 7), "
            "a column softmax (ch. 5), an explicit Euler step (ch. 3)"),
    Chapter(1, "01_autodiff", "reverse-mode autodiff on NumPy",
            ("minimanc.autodiff", "minimanc.engine"), ("minimanc.tree", "minimanc.viz.graph"),
            "unbroadcasting, VJPs, the tape's topological order, grad, the computation graph"),
    Chapter(2, "02_training", "layers, conv2d, Adam",
            ("minimanc.layers", "minimanc.optim", "minimanc.autodiff.nn"), (),
            "convolution, pooling, initialisation and optimisers"),
    Chapter(3, "03_dmp", "point-attractor DMP, damping ratio, stability",
            ("minimanc.dmp",), (),
            "DMP damping, step stability, forcing term"),
    Chapter(4, "04_quaternions", "quaternion log/exp and DMP",
            ("minimanc.quaternion",), (),
            "quaternion product, log, exp, orientation error, integration"),
    Chapter(5, "05_vagn", "the soft automaton",
            ("minimanc.vagn",), ("minimanc.viz.automaton",),
            "the vAGN soft automaton"),
    Chapter(6, "06_cam", "visual predicates and CAM saliency",
            ("minimanc.cam",), ("minimanc.viz.saliency",),
            "class activation maps, Grad-CAM, baselines, q-state saliency"),
    Chapter(7, "07_world", "nuScenes-style BEV world and data",
            ("minimanc.world",), ("minimanc.viz.world", "minimanc.cli.data"),
            "frames, the BEV raster, the IDM, the lane-following expert"),
    Chapter(8, "08_manc", "the assembled controller",
            ("minimanc.models", "minimanc.inputs", "minimanc.train"), (),
            "assembling MANC"),
    Chapter(9, "09_behavior_cloning", "training, closed loop, the paper's studies",
            ("minimanc.rollout", "minimanc.metrics", "minimanc.studies"),
            ("minimanc.viz.study", "minimanc.viz.explain", "minimanc.cli.reproduce",
             "minimanc.cli.results"),
            "the MANC step, the closed loop, a metric"),
    Chapter(10, "10_highway_sandbox", "the controller in highway-env",
            ("minimanc.highway",), ("minimanc.cli.highway",),
            "the controller in a real driving simulator"),
    Chapter(11, "11_dagger", "behaviour cloning's drift and DAgger",
            ("minimanc.dagger",),
            ("minimanc.studies.dagger_study", "minimanc.viz.dagger", "minimanc.cli.dagger"),
            "the DAgger schedule, the mixture, aggregation, the budget"),
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
        modules = ", ".join(f"`{m}`" for m in chapter.modules)
        lines.append(f"| {chapter.code} | `{chapter.notebook}` | {chapter.title} — {modules} |")
    return "".join(line + "\n" for line in lines)
