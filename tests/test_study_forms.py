"""The study's named forms (paper, learner): what they set, how table1.md and the command say
which ran."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from minimanc import cli, models, world
from minimanc.studies import PRESETS
from minimanc.studies.config import (
    FORMS,
    LEARNER_MODEL,
    LEARNER_RASTER,
    StudyConfig,
    form_of,
    model_text,
    with_form,
)


def test_the_presets_are_in_the_learner_form_and_the_papers_form_changes_only_how_they_learn():
    for name in ("quick", "full", "paper"):
        assert form_of(PRESETS[name]) == "learner"
        learner = PRESETS[name]
        assert learner.raster == LEARNER_RASTER and learner.raster.encoding == "channels"
        assert learner.dagger_rounds == 10 and learner.model == LEARNER_MODEL
        assert learner.round_epochs == (1 if name == "quick" else 2)  # a budget, not the form
        paper = with_form(learner, "paper")
        assert form_of(paper) == "paper" and not paper.on_policy
        assert paper.raster == world.RasterConfig() and paper.model == models.ModelConfig()
        assert replace(paper, raster=LEARNER_RASTER, dagger_rounds=10,
                       model=LEARNER_MODEL) == learner
        assert with_form(paper, "learner") == learner
    assert form_of(PRESETS["tiny"]) is None  # its 32 px raster is neither


def test_a_form_not_named_is_refused():
    with pytest.raises(ValueError, match="form must be one of \\['learner', 'paper'\\]"):
        with_form(StudyConfig(), "rgb")


def test_the_learner_raster_reaches_60_m_ahead_at_the_devkits_scale():
    paper = world.RasterConfig()
    assert LEARNER_RASTER.metres_ahead == 60.0
    assert LEARNER_RASTER.input_shape == (90, 64, 12)
    # the same metres per pixel as the devkit's raster, along and across
    along = (LEARNER_RASTER.metres_ahead + LEARNER_RASTER.metres_behind) / LEARNER_RASTER.size
    assert along == pytest.approx((paper.metres_ahead + paper.metres_behind) / paper.size,
                                  rel=0.02)


def test_model_text_names_what_departs_from_the_librarys_models():
    assert model_text(models.ModelConfig()) == ""
    assert model_text(LEARNER_MODEL) == ("eq. 7 over the flattened features, 64 predicates, "
                                         "MANC's gains over q ⊕ p, the DMP's goal 10 m ahead")
    assert model_text(models.ModelConfig(position_lookahead=6.0, hidden=32)) == \
        "the DMP's goal 6 m + 2 s × speed ahead, hidden = 32"
    with pytest.raises(ValueError, match="model must be a minimanc.models.ModelConfig"):
        model_text("flatten")


def _seen_config(monkeypatch, tmp_path, argv):
    from minimanc.cli import reproduce as cmd

    seen = {}

    def fake(config, out, **kwargs):
        seen["config"], seen["out"] = config, out
        raise SystemExit(0)

    monkeypatch.setattr(cmd, "reproduce", fake)
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit):
        cli.main(["reproduce", "--quick", *argv])
    return seen


def test_reproduce_form_sets_the_form_and_its_own_output_folder(monkeypatch, tmp_path):
    seen = _seen_config(monkeypatch, tmp_path, ["--form", "paper"])
    assert seen["config"] == with_form(PRESETS["quick"], "paper")
    assert seen["out"].name == "quick-paper"
    seen = _seen_config(monkeypatch, tmp_path, ["--form", "learner"])  # the preset's own form
    assert seen["config"] == PRESETS["quick"] and seen["out"].name == "quick"
    seen = _seen_config(monkeypatch, tmp_path, [])
    assert seen["config"] == PRESETS["quick"] and seen["out"].name == "quick"


def test_reproduce_refuses_the_learner_form_on_recorded_data(monkeypatch, tmp_path, capsys):
    from minimanc.cli import reproduce as cmd

    monkeypatch.setattr(cmd, "data_config", lambda config, path: config)
    monkeypatch.setattr(cmd, "is_recorded", lambda config: True)
    monkeypatch.setattr(cmd, "reproduce", lambda *a, **k: pytest.fail("ran"))
    code = cli.main(["reproduce", "--quick", "--data", "x.npz", "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "add --form paper" in err[0], err
    assert set(FORMS) == {"paper", "learner"}


def test_the_explainability_figures_draw_the_learner_raster_with_its_past(tmp_path):
    """Fig. 3–4 and the GIF on a channels raster with history: the BEV panel is the raster
    the policy saw (its own poses and their past), painted for people."""
    import matplotlib

    matplotlib.use("Agg")
    from minimanc import models, rollout, train
    from minimanc.viz import explain
    from minimanc.world.history import history_of

    raster = world.RasterConfig(size=24, cols=16, metres_ahead=30.0, encoding="channels",
                                route=True, history=2)
    ds = world.generate(2, seed=0, raster=raster)
    cfg = models.ModelConfig(input_shape=raster.input_shape, channels=(4, 4, 4), hidden=8,
                             predicate_readout="flatten")
    fit = train.fit("manc", ds, cfg, train.TrainConfig(epochs=1, batch_size=8,
                                                      max_steps_per_epoch=1), progress=False)
    traj = rollout.closed_loop(fit, ds, progress=False)
    human = rollout.human(ds)
    t = 4
    fig = explain.plot_explain_trace(traj, human, ds, 0, bev_steps=[t])
    shown = [im.get_array() for ax in fig.axes for im in ax.images]
    past = history_of(traj.ego[0], ds.ado[0], ds.ado_valid[0], 2, frames=[t])
    want = world.to_rgb(world.rasterize(ds.maps[0], traj.ego[0, t], ds.ado[0, t],
                                        ds.ado_valid[0, t], raster, history=past), raster)
    assert any(np.array_equal(np.asarray(a), want) for a in shown)
    assert want.shape == (24, 16, 3)
    fig = explain.plot_saliency_steps(fit.params, fit.cfg, traj, ds, 0, [1, t])
    assert len(fig.axes) == 2 * (cfg.n_states + 1)
    gif = explain.save_rollout_gif(traj, human, ds, 0, tmp_path / "r.gif")
    assert gif.exists() and gif.stat().st_size > 0
