"""Tests for the direct heads' speed change (``ModelConfig.speed_output``) and the loss's
speed scale (``TrainConfig.speed_scale``, :func:`minimanc.train.batches.control_std`)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from minimanc import engine, inputs, models, train, world
from minimanc.train.batches import control_std

CFG = models.ModelConfig(image_size=16, channels=(4, 8), n_predicates=5, n_states=4, hidden=8,
                         k_targets=6, setting="parity")
DIRECT = [n for n in models.names() if n not in models.dmp_models()]


def _obs(rng, b=3):
    k = CFG.k_targets
    return {"bev": rng.random((b, 16, 16, 3)), "goal": rng.normal(size=(b, 3)) * 20,
            "lane_target": np.stack([4.0 * np.arange(1, k + 1), np.zeros(k)], -1)
            + rng.normal(0, 0.5, (b, k, 2)),
            "motion": np.stack([rng.uniform(0, 12, b), rng.normal(0, 0.1, b)], -1),
            "goal_bev": rng.random((b, 16, 16, 3))}


def _both(name, seed):
    """The observation and the controls of one step with speed_output "level" and "change"
    (same parameters, same observation)."""
    eng = engine("numpy")
    rng = np.random.default_rng(seed)
    params = models.init(name, rng, CFG)
    obs = inputs.select(_obs(rng), models.get(name), "parity")
    state = models.initial_state(name, 3, CFG)
    level, _, _ = models.step(name, params, obs, state, CFG, eng)
    change, _, _ = models.step(name, params, obs, state, replace(CFG, speed_output="change"),
                               eng)
    return obs, np.asarray(level), np.asarray(change)


@pytest.mark.parametrize("name", DIRECT)
def test_change_output_is_the_current_speed_plus_a_scaled_head_output(name):
    obs, level, change = _both(name, 1)
    k = models.CHANGE_SCALE / models.CONTROL_SCALE[0]
    np.testing.assert_allclose(change[:, 0], obs["motion"][:, 0] + k * level[:, 0], rtol=1e-5,
                               atol=1e-5)
    np.testing.assert_allclose(change[:, 1], level[:, 1], rtol=1e-6)


@pytest.mark.parametrize("name", models.dmp_models())
def test_the_dmp_heads_do_not_change_with_the_option(name):
    _, a, b = _both(name, 2)
    np.testing.assert_array_equal(a, b)


def test_change_output_refuses_a_model_that_does_not_see_its_motion():
    cfg = replace(CFG, setting="paper", speed_output="change")
    rng = np.random.default_rng(0)
    params = models.init("cnn", rng, cfg)
    obs = inputs.select(_obs(rng), models.get("cnn"), "paper")
    with pytest.raises(ValueError, match="needs a model that sees 'motion'"):
        models.step("cnn", params, obs, {}, cfg, engine("numpy"))


def test_bad_options_raise_and_the_default_keeps_the_old_config_dict():
    with pytest.raises(ValueError, match="speed_output must be one of"):
        models.ModelConfig(speed_output="delta")
    with pytest.raises(ValueError, match="speed_scale must be 'level' or 'change'"):
        train.TrainConfig(speed_scale="accel")
    assert "speed_output" not in models.ModelConfig().to_dict()
    assert models.ModelConfig(speed_output="change").to_dict()["speed_output"] == "change"


def test_change_scale_is_the_std_of_the_logged_speed_change():
    ds = world.generate(3, seed=4)
    c = np.asarray(ds.controls, dtype=np.float64)
    first = c[:, :1, 0]  # the speed before the first step is the first step's speed
    prev = np.concatenate([first, c[:, :-1, 0]], axis=1)
    want = np.std(c[..., 0] - prev)
    sd = control_std(ds, speed="change")
    assert sd[0] == pytest.approx(want, rel=1e-6)
    assert sd[1] == pytest.approx(c[..., 1].std(), rel=1e-9)
    assert control_std(ds)[0] == pytest.approx(c[..., 0].std(), rel=1e-9)
    sub = control_std(ds, [0, 2], speed="change")
    cs, ps = c[[0, 2]], prev[[0, 2]]
    assert sub[0] == pytest.approx(np.std(cs[..., 0] - ps), rel=1e-6)
    with pytest.raises(ValueError, match="speed must be 'level' or 'change'"):
        control_std(ds, speed="accel")
