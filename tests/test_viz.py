"""Tests for minimanc.viz: the figures apart from the math, and the old names forwarded to them."""

from __future__ import annotations

import ast
import importlib
import importlib.util
import re
import subprocess
import sys
import types
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from hypothesis import given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from minimanc import cam, plots, vagn  # noqa: E402
from minimanc.viz import automaton, explain, saliency, study, style  # noqa: E402
from minimanc.viz.forward import forwarder  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent

FORWARDED = {
    cam: (saliency, ("paper_cmap", "PAPER_CMAP", "blend", "overlay", "plot_q_saliency")),
    vagn: (automaton, ("plot_automaton", "plot_q_heatmap")),
    plots: (style, ("MODEL_LABELS", "MODEL_COLOURS")),
}


# --------------------------------------------------------------------- no plotting in the math
def test_math_model_and_viz_modules_import_no_plotting_library():
    code = ("import sys, minimanc.models, minimanc.cam, minimanc.vagn, minimanc.plots, "
            "minimanc.viz.automaton, minimanc.viz.saliency, minimanc.viz.study, "
            "minimanc.viz.explain; import minimanc.cam as c, minimanc.vagn as v; "
            "c.blend, c.overlay, c.plot_q_saliency, v.plot_automaton, v.plot_q_heatmap; "
            "print(sorted({m.split('.')[0] for m in sys.modules} & {'matplotlib', 'PIL'}))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, cwd=ROOT)
    assert out.stdout.strip() == "[]", out.stdout


@pytest.mark.parametrize("path", ["minimanc/cam.py", "minimanc/vagn.py"])
def test_math_modules_hold_no_plotting_code(path):
    tree = ast.parse((ROOT / path).read_text())
    imported = {a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
    imported |= {n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)}
    assert not {m for m in imported if m.split(".")[0] in ("matplotlib", "PIL")}, imported
    assert "plt" not in {n.id for n in ast.walk(tree) if isinstance(n, ast.Name)}


def _docstring_problems():
    """tests/test_docstrings.py's numpydoc checker (loaded from its file)."""
    spec = importlib.util.spec_from_file_location("docstring_checks",
                                                  ROOT / "tests" / "test_docstrings.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod.problems


@pytest.mark.parametrize("name", ["automaton", "saliency", "style", "forward"])
def test_viz_functions_carry_numpydoc_sections(name):
    # the figures of chapters 5-6 were checked through vagn's and cam's __all__ before the move
    module = importlib.import_module(f"minimanc.viz.{name}")
    assert module.__all__ and _docstring_problems()(module) == []


@pytest.mark.parametrize("name", ["automaton", "saliency", "study", "explain"])
def test_viz_module_docstring_opens_with_its_chapter(name):
    doc = importlib.import_module(f"minimanc.viz.{name}").__doc__
    assert re.match(r"Chapter \d+ — ", doc), doc[:80]


# --------------------------------------------------------------------- the old names
@pytest.mark.parametrize("module", list(FORWARDED), ids=lambda m: m.__name__)
def test_old_names_are_the_viz_objects_and_listed(module):
    target, names = FORWARDED[module]
    for name in names:
        if name in ("PAPER_CMAP", "MODEL_LABELS", "MODEL_COLOURS"):  # built when asked
            assert getattr(module, name) == getattr(target, name)
        else:
            assert getattr(module, name) is getattr(target, name)
        assert name in dir(module)
        assert name in module.__doc__
    with pytest.raises(AttributeError, match=f"module '{module.__name__}' has no attribute"):
        module.no_such_figure  # noqa: B018


def test_plots_reexports_every_figure_of_the_viz_modules():
    for mod in (study, explain, style):
        for name in mod.__all__:
            if name in plots.__all__:
                assert getattr(plots, name) is getattr(mod, name)
    shown = {n for mod in (study, explain) for n in mod.__all__ if n.startswith("plot_")}
    assert shown <= set(plots.__all__)


def test_forwarder_reads_the_target_on_every_access():
    target = types.ModuleType("minimanc_fake_target")
    target.value = 1
    sys.modules[target.__name__] = target
    try:
        namespace = {"own": 0}
        get, names = forwarder("fake", namespace, {"value": target.__name__})
        assert get("value") == 1
        target.value = 2
        assert get("value") == 2  # not cached
        assert names() == ["own", "value"]
        with pytest.raises(AttributeError, match="module 'fake' has no attribute 'other'"):
            get("other")
    finally:
        del sys.modules[target.__name__]


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
    assert explain.check_scene(rows, np.int64(2)) == 2
    with pytest.raises(ValueError, match=r"scene must index the rollout's 3 rows; got scene=3"):
        explain.check_scene(rows, 3)
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
    c = saliency.PAPER_CMAP
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
    np.testing.assert_allclose(full, saliency.PAPER_CMAP(up)[..., :3])
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
    assert [t.get_text() for t in ax.get_xticklabels()][0] == plots.model_label("manc")
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
