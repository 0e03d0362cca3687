"""Tests for minimanc.viz: the figures apart from the math, behind one door."""

from __future__ import annotations

import ast
import importlib
import importlib.util
import re
import subprocess
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from hypothesis import given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

import minimanc.viz  # noqa: E402
from minimanc import cam, vagn  # noqa: E402
from minimanc.viz import automaton, dagger, explain, saliency, study, style  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
VIZ_MODULES = ("style", "graph", "automaton", "saliency", "world", "study", "explain",
               "highway", "dagger", "investigation", "exercises")


# --------------------------------------------------------------------- no plotting in the math
def _plotting_modules_after(imports: str) -> str:
    code = (f"import sys; {imports}; "
            "print(sorted({m.split('.')[0] for m in sys.modules} & {'matplotlib', 'PIL'}))")
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=True, cwd=ROOT).stdout.strip()


def test_math_model_world_and_viz_modules_import_no_plotting_library():
    out = _plotting_modules_after("import minimanc.models, minimanc.cam, minimanc.vagn, "
                                  "minimanc.world, minimanc.viz")
    assert out == "[]", out


def test_the_world_imports_no_figure_module():
    code = ("import sys, minimanc.world; "
            "print(sorted(m for m in sys.modules if m.startswith('minimanc.viz')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, cwd=ROOT).stdout.strip()
    assert out == "[]", out


@pytest.mark.parametrize("path", ["minimanc/cam.py", "minimanc/vagn/automaton.py",
                                  "minimanc/vagn/fused.py", "minimanc/autodiff/graph.py",
                                  "minimanc/dagger/loop.py"])
def test_math_modules_hold_no_plotting_code(path):
    tree = ast.parse((ROOT / path).read_text())
    imported = {a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
    imported |= {n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)}
    assert not {m for m in imported
                if m.split(".")[0] in ("matplotlib", "PIL") or m.startswith("minimanc.viz")}
    assert "plt" not in {n.id for n in ast.walk(tree) if isinstance(n, ast.Name)}


def _module_level_names(tree: ast.Module) -> list[str]:
    names = []
    for node in tree.body:
        if isinstance(node, ast.FunctionDef):
            names.append(node.name)
        elif isinstance(node, ast.Assign | ast.AnnAssign):
            names += [t.id for t in ast.walk(node)
                      if isinstance(t, ast.Name) and isinstance(t.ctx, ast.Store)]
    return names


def test_no_module_defines_a_module_level_getattr_or_dir():
    found = [f"{path.relative_to(ROOT)}: {name}"
             for path in sorted((ROOT / "minimanc").rglob("*.py"))
             for name in _module_level_names(ast.parse(path.read_text()))
             if name in ("__getattr__", "__dir__")]
    assert found == []


def test_viz_is_the_one_door_for_figures():
    assert minimanc.viz.__all__ == sorted(VIZ_MODULES)
    for name in VIZ_MODULES:
        assert getattr(minimanc.viz, name) is importlib.import_module(f"minimanc.viz.{name}")
    for gone in ("plots.py", "viz/forward.py", "world/viz.py"):  # the old doors
        assert not (ROOT / "minimanc" / gone).exists(), gone


def _docstring_problems():
    """tests/test_docstrings.py's numpydoc checker (loaded from its file)."""
    spec = importlib.util.spec_from_file_location("docstring_checks",
                                                  ROOT / "tests" / "test_docstrings.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod.problems


@pytest.mark.parametrize("name", ["automaton", "saliency", "style", "dagger", "graph", "highway",
                                  "investigation"])
def test_viz_functions_carry_numpydoc_sections(name):
    # the figures of chapters 5-6 were checked through vagn's and cam's __all__ before the move
    module = importlib.import_module(f"minimanc.viz.{name}")
    assert module.__all__ and _docstring_problems()(module) == []


@pytest.mark.parametrize("name", ["graph", "automaton", "saliency", "world", "study", "explain",
                                  "highway", "dagger", "investigation"])
def test_viz_module_docstring_opens_with_its_chapter(name):
    doc = importlib.import_module(f"minimanc.viz.{name}").__doc__
    assert re.match(r"Chapter \d+ — ", doc), doc[:80]


def test_model_labels_and_colours_list_every_registered_model_and_the_references():
    from minimanc import models

    labels, colours = style.model_labels(), style.model_colours()
    assert list(labels) == ["human", *models.names(), "dmp_prior"]
    assert set(colours) == set(style.REFERENCE_COLOURS) | set(models.names())
    for name in models.names():
        assert labels[name] == style.model_label(name) == models.spec(name).label
        assert colours[name] == style.model_colour(name) == models.spec(name).colour


# --------------------------------------------------------------------- shared pieces
@given(st.integers(1, 9))
@settings(max_examples=20, deadline=None)
def test_state_labels(n):
    assert style.state_labels(None, n) == [f"$q_{{{i}}}$" for i in range(n)]
    names = [f"s{i}" for i in range(n)]
    assert style.state_labels(names, n) == names
    with pytest.raises(ValueError, match=f"labels must have N = {n} entries; got {n + 1}"):
        style.state_labels([*names, "x"], n)


def test_check_scene_and_check_metrics():
    rows = np.zeros((3, 2))
    assert explain.check_scene_index(rows, np.int64(2)) == 2
    with pytest.raises(ValueError, match=r"scene must index the rollout's 3 rows; got scene=3"):
        explain.check_scene_index(rows, 3)
    style.check_metrics(["ade", "goal_distance"])
    with pytest.raises(ValueError, match="metrics must be names from .*; got 'speed'"):
        style.check_metrics(["ade", "speed"])


def test_clear_ticks():
    fig, ax = plt.subplots()
    assert style.clear_ticks(ax) is ax
    assert list(ax.get_xticks()) == [] and list(ax.get_yticks()) == []
    plt.close(fig)


# --------------------------------------------------------------------- chapter 5 (vAGN)
def test_plot_automaton_edge_widths_follow_probabilities():
    from matplotlib.patches import Circle, FancyArrowPatch

    T = np.array([[0.7, 0.2, 0.1], [0.2, 0.6, 0.05], [0.1, 0.2, 0.85]])
    fig, ax = plt.subplots()
    automaton.plot_automaton(T, ax=ax, max_width=10.0, q=np.array([0.2, 0.3, 0.5]))
    arrows = [p for p in ax.patches if isinstance(p, FancyArrowPatch)]
    rings = [p for p in ax.patches if isinstance(p, Circle) and not p.get_fill()]
    assert len(arrows) == 6 and len(rings) == 3
    widths = sorted(a.get_linewidth() for a in arrows)
    expected = sorted(10.0 * T[i, j] for i in range(3) for j in range(3) if i != j)
    np.testing.assert_allclose(widths, expected)
    plt.close(fig)
    fig, ax = plt.subplots()
    automaton.plot_automaton(T, ax=ax, min_prob=0.15)
    arrows = [p for p in ax.patches if isinstance(p, FancyArrowPatch)]
    assert len(arrows) == 3  # 0.2, 0.2, 0.2 survive; 0.1, 0.1, 0.05 are hidden
    plt.close(fig)


def test_plot_automaton_refuses_bad_input():
    T = np.full((3, 3), 1 / 3)
    with pytest.raises(ValueError, match="T must have shape"):
        automaton.plot_automaton(np.full((2, 3, 3), 1 / 3))
    with pytest.raises(ValueError, match="T must be column-stochastic"):
        automaton.plot_automaton(2 * T)
    with pytest.raises(ValueError, match="labels must have N = 3 entries; got 2"):
        automaton.plot_automaton(T, labels=["a", "b"])
    with pytest.raises(ValueError, match="q must be a probability distribution"):
        automaton.plot_automaton(T, q=np.ones(3))
    plt.close("all")


def test_plot_q_heatmap_shows_the_distribution():
    qs = vagn.rollout(vagn.uniform_state(3), np.random.default_rng(0).random((10, 2)),
                      vagn.init_vagn(np.random.default_rng(1), 2, 3))
    fig, ax = plt.subplots()
    automaton.plot_q_heatmap(qs, ax=ax, labels=["a", "b", "c"])
    np.testing.assert_allclose(ax.images[0].get_array(), qs.T)
    assert [t.get_text() for t in ax.get_yticklabels()] == ["a", "b", "c"]
    plt.close(fig)
    with pytest.raises(ValueError, match="qs must be a probability distribution"):
        automaton.plot_q_heatmap(qs * 2)
    with pytest.raises(ValueError, match="labels must have N = 3 entries; got 1"):
        automaton.plot_q_heatmap(qs, labels=["a"])
    plt.close("all")


# --------------------------------------------------------------------- chapter 6 (CAM)
def test_paper_cmap_ranks_yellow_red_cyan_magenta():
    c = saliency.paper_cmap()
    assert c is saliency.paper_cmap()  # built once
    np.testing.assert_allclose(c(1.0)[:3], [1, 1, 0])  # high: yellow
    np.testing.assert_allclose(c(2 / 3)[:3], [1, 0, 0], atol=0.01)  # red
    np.testing.assert_allclose(c(1 / 3)[:3], [0, 1, 1], atol=0.01)  # cyan
    np.testing.assert_allclose(c(0.0)[:3], [1, 0, 1])  # low: magenta


def test_blend_and_overlay():
    rng = np.random.default_rng(8)
    img = rng.integers(0, 256, (8, 8, 3), dtype=np.uint8)
    sal = rng.standard_normal((4, 4))
    np.testing.assert_allclose(saliency.blend(img, sal, alpha=0.0), img / 255.0)
    full = saliency.blend(img, sal, alpha=1.0)
    up = cam.minmax_normalize(cam.upsample(sal, 8))
    np.testing.assert_allclose(full, saliency.paper_cmap()(up)[..., :3])
    r, c = cam.peak_location(up)
    np.testing.assert_allclose(full[r, c], [1, 1, 0])  # the peak is drawn yellow
    fig, ax = plt.subplots()
    saliency.overlay(img, sal, ax=ax, alpha=0.4, title="t")
    np.testing.assert_allclose(ax.images[0].get_array(), saliency.blend(img, sal, alpha=0.4))
    assert ax.get_title() == "t" and list(ax.get_xticks()) == []
    plt.close(fig)
    axes = saliency.plot_q_saliency(img, rng.standard_normal((3, 8, 8)),
                                    np.array([0.2, 0.3, 0.5]))
    assert len(axes) == 4 and axes[3].get_title() == "$q_{2}$: P = 0.50"
    assert axes[0].get_title() == "BEV input" and list(axes[0].get_yticks()) == []
    plt.close("all")
    with pytest.raises(ValueError, match="alpha"):
        saliency.blend(img, sal, alpha=1.5)
    with pytest.raises(ValueError, match="saliency must have shape"):
        saliency.blend(img, np.ones((2, 4, 4)))
    with pytest.raises(ValueError, match="labels must have N = 3 entries; got 2"):
        saliency.plot_q_saliency(img, np.ones((3, 8, 8)), np.ones(3) / 3, labels=["a", "b"])
    with pytest.raises(ValueError, match=r"saliency must be \(N, H, W\) and q \(N,\)"):
        saliency.plot_q_saliency(img, np.ones((3, 8, 8)), np.ones(2) / 2)
    plt.close("all")


# --------------------------------------------------------------------- chapter 9 (study)
def _agg(**means):
    return {k: {"mean": v, "std": v / 10} for k, v in means.items()}


def test_plot_table1_bars_are_the_means_in_groups():
    table = {"paper": {"manc": _agg(ade=1.0), "cnn": _agg(ade=2.0)},
             "privileged": {"manc": _agg(ade=3.0), "other": _agg(ade=4.0)}}
    fig = study.plot_table1(table, metrics=("ade",))
    ax = fig.axes[0]
    bars = ax.patches
    # settings in order, each over the models (manc, cnn, other); missing entries are nan
    heights = [b.get_height() for b in bars]
    np.testing.assert_array_equal(heights, [1.0, 2.0, np.nan, 3.0, np.nan, 4.0])
    centres = [b.get_x() + b.get_width() / 2 for b in bars]
    np.testing.assert_allclose(centres, [-0.2, 0.8, 1.8, 0.2, 1.2, 2.2])
    assert [b.get_hatch() or "" for b in bars] == [""] * 3 + ["//"] * 3
    assert [t.get_text() for t in ax.get_xticklabels()][0] == style.model_label("manc")
    assert ax.get_title() == style.METRIC_LABELS["ade"]
    assert [t.get_text() for t in ax.get_legend().get_texts()] == ["paper", "privileged"]
    plt.close(fig)


def test_plot_families_bars_are_the_means_in_groups():
    families = {"manc": {"straight": _agg(ade=1.0, cross_track=0.5),
                         "left_turn": _agg(ade=2.0, cross_track=0.25)},
                "cnn": {"straight": _agg(ade=3.0, cross_track=1.0)}}
    fig = study.plot_families(families, metrics=("ade", "cross_track"), title="T")
    for ax, metric in zip(fig.axes, ("ade", "cross_track")):
        heights = [b.get_height() for b in ax.patches]
        expected = [families[m].get(f, {}).get(metric, {}).get("mean", np.nan)
                    for m in ("manc", "cnn") for f in ("straight", "left_turn")]
        np.testing.assert_array_equal(heights, expected)
        assert [t.get_text() for t in ax.get_xticklabels()] == ["straight", "left-turn"]
        assert ax.get_title() == style.METRIC_LABELS[metric]
    assert fig._suptitle.get_text() == "T"
    plt.close(fig)


# --------------------------------------------------------------------- chapter 11 (DAgger)
def test_plot_rounds_draws_each_run_over_its_rounds_and_bc_as_its_mean():
    from types import SimpleNamespace as NS

    run = NS(name="manc", rounds=[NS(round=0, metrics={"ade": 3.0}),
                                  NS(round=1, metrics={"ade": 2.0}),
                                  NS(round=2, metrics={})])  # a round without the metric
    bc = [NS(metrics={"ade": 4.0}), NS(metrics={"ade": 2.0})]
    ax = dagger.plot_rounds([run], "ade", bc)
    line, mean = ax.get_lines()
    np.testing.assert_array_equal(line.get_xdata(), [0, 1])
    np.testing.assert_array_equal(line.get_ydata(), [3.0, 2.0])
    np.testing.assert_array_equal(mean.get_ydata(), [3.0, 3.0])  # BC: the mean of the runs
    assert [t.get_text() for t in ax.get_legend().get_texts()] == ["DAgger manc",
                                                                   "BC, same budget"]
    assert ax.get_ylabel() == "ade"
    plt.close(ax.figure)
    ax = dagger.plot_rounds([run], "ade")
    assert len(ax.get_lines()) == 1  # no BC line without BC runs
    plt.close(ax.figure)


def test_plot_study_rounds_draws_dagger_by_round_and_bc_per_model():
    res = {"models": {"manc": {"by_round": [{"ade": {"mean": 3.0}}, {"ade": {"mean": 2.5}}],
                               "bc": {"ade": {"mean": 2.8}}},
                      "cnn": {"by_round": [{"ade": {"mean": 4.0}}, {"ade": {"mean": 3.0}}],
                              "bc": {"ade": {"mean": 3.5}}}}}
    fig = dagger.plot_study_rounds(res, "ade")
    ax = fig.axes[0]
    lines = ax.get_lines()  # per model: DAgger by round, then BC
    np.testing.assert_array_equal(lines[0].get_ydata(), [3.0, 2.5])
    np.testing.assert_array_equal(lines[1].get_ydata(), [2.8, 2.8])
    np.testing.assert_array_equal(lines[2].get_ydata(), [4.0, 3.0])
    assert lines[0].get_color() == lines[1].get_color() == style.model_colour("manc")
    assert [t.get_text() for t in ax.get_legend().get_texts()] == [
        "MANC DAgger", "MANC BC", "CNN DAgger", "CNN BC"]
    assert ax.get_ylabel() == style.METRIC_LABELS["ade"]
    plt.close(fig)


# --------------------------------------------------------------------- the exercises' figures
def _stub():
    raise NotImplementedError("Exercise ex99_1: to do")


def test_automaton_panels_fall_back_to_the_reference():
    W = vagn.init_vagn(np.random.default_rng(0), 2, 3, scale=1.0)
    T = vagn.transition_matrix(np.array([1.0, 0.0]), W)
    qs = vagn.rollout(vagn.uniform_state(3), np.ones((4, 2)), W)
    axes = automaton.plot_automaton_attempts([("T", "T", lambda: T, T), ("todo", "T", _stub, T),
                                              ("bad", "q", lambda: -qs, None),
                                              ("q", "q", lambda: qs, qs)])
    titles = [ax.get_title() for ax in axes]
    assert titles[0] == "T (yours)" and titles[3] == "q (yours)"
    assert titles[1].startswith("todo: reference\nyours: NotImplementedError")
    assert titles[2].startswith("bad: nothing\nyours: ")         # not a distribution
    assert axes[1].patches or axes[1].collections               # the reference was drawn


def test_automaton_panels_refuse_unknown_kinds_and_axes_counts():
    with pytest.raises(ValueError, match="kinds must be 'T' or 'q'"):
        automaton.plot_automaton_attempts([("x", "graph", _stub, None)])
    _, axes = plt.subplots(1, 2)
    with pytest.raises(ValueError, match="expected 1 axes, got 2"):
        automaton.plot_automaton_attempts([("x", "T", _stub, None)], axes=axes)


def test_overlays_draw_yours_or_name_the_error():
    image = np.zeros((4, 4, 3), np.uint8)
    ramp = np.arange(16.0).reshape(4, 4)
    axes = saliency.plot_overlay_attempts(image, [("mine", lambda: ramp, None),
                                                  ("todo", _stub, ramp), ("none", _stub, None)])
    assert len(axes) == 4 and axes[1].get_title() == "mine"
    assert axes[2].get_title().startswith("todo: reference\nyours: NotImplementedError")
    assert axes[2].images and not axes[3].images
    with pytest.raises(ValueError, match="expected 2 axes, got 1"):
        saliency.plot_overlay_attempts(image, [("x", _stub, None)], axes=[axes[0]])
