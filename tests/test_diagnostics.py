"""Chapter 9 — why a driver fails (minimanc.metrics.diagnostics): regimes by hand, the error
split by regime adds up, and a drive into a standing car is counted, at fault, at its speed."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from minimanc.metrics.diagnostics import (
    REGIMES,
    collision_taxonomy,
    error_by_regime,
    linear_probe,
    regimes,
)


def test_regimes_by_hand():
    inf = np.inf
    lab = regimes(speed=[10.0, 10.0, 10.0, 10.0, 2.0],
                  gap=[inf, 20.0, inf, 20.0, 9.0],
                  stop=[inf, inf, inf, 10.0, inf],
                  acceleration=[0.0, 0.0, -2.0, -2.0, 0.0])
    assert [REGIMES[i] for i in lab] == ["cruising", "following", "braking", "yielding",
                                         "following"]


def test_regimes_refuse_bad_input():
    with pytest.raises(ValueError, match="NaN"):
        regimes([np.nan], [1.0], [1.0], [0.0])
    with pytest.raises(ValueError, match="2 states"):
        regimes([1.0, 2.0], [1.0], [1.0, 1.0], [0.0, 0.0])


@given(st.lists(st.integers(0, len(REGIMES) - 1), min_size=1, max_size=40),
       st.integers(0, 2**31 - 1))
def test_the_split_adds_up(labels, seed):
    rng = np.random.default_rng(seed)
    lab = np.array(labels)
    p, y = rng.normal(size=(len(lab), 2)), rng.normal(size=(len(lab), 2))
    out = error_by_regime(p, y, lab)
    assert set(out) == {REGIMES[i] for i in set(labels)}
    assert sum(r["states"] for r in out.values()) == len(lab)
    # the regimes' mean squared errors, weighted by their shares, are the total's
    total = ((p - y) ** 2).mean(axis=0)
    parts = sum(r["share"] * np.array([r["rmse_0"], r["rmse_1"]]) ** 2 for r in out.values())
    np.testing.assert_allclose(parts, total, rtol=1e-9)


def test_error_by_regime_refuses_bad_input():
    with pytest.raises(ValueError, match="shape"):
        error_by_regime(np.zeros((3, 2)), np.zeros((3, 1)), np.zeros(3, int))
    with pytest.raises(ValueError, match="finite"):
        error_by_regime(np.full((1, 2), np.nan), np.zeros((1, 2)), np.zeros(1, int))


def test_a_drive_into_a_standing_car():
    T = 10
    t = np.arange(T) * 0.5
    ego = np.zeros((1, T, 3))
    ego[0, :, 0] = 10.0 * t  # 10 m/s along x
    human = np.zeros((1, T, 3))
    human[0, :, 0] = np.minimum(4.0 * t, 20.0)  # slower, stops before the car
    ado = np.zeros((1, T, 1, 5))
    ado[..., 0], ado[..., 3], ado[..., 4] = 30.0, 4.5, 1.9  # standing 30 m ahead
    valid = np.ones((1, T, 1), bool)
    out = collision_taxonomy(ego, ado, valid, human)
    assert out["stopped_ado"] == 1.0 and out["at_fault"] == 1.0
    assert sum(out[k] for k in ("stopped_ego", "stopped_ado", "rear", "front", "lateral")) == 1
    assert out["ego_speed"] == pytest.approx(10.0) and out["faster"] == 1.0
    assert out["human_speed"] < 10.0
    # the human's own drive touches nothing
    clean = collision_taxonomy(human, ado, valid, human)
    assert clean["at_fault"] == 0.0 and np.isnan(clean["ego_speed"])


def test_taxonomy_refuses_another_shape():
    with pytest.raises(ValueError, match="human"):
        collision_taxonomy(np.zeros((1, 4, 3)), np.zeros((1, 4, 1, 5)),
                           np.zeros((1, 4, 1), bool), np.zeros((1, 5, 3)))


def test_linear_probe_reads_a_linear_quantity_and_not_noise():
    rng = np.random.default_rng(0)
    z = rng.normal(size=(600, 20))
    w = rng.normal(size=(20,))
    y = np.stack([z @ w + 3.0, rng.normal(size=600)], axis=1)  # linear, and independent noise
    out = linear_probe(z[:400], y[:400], z[400:], y[400:], ridge=1e-3)
    assert out["r2"][0] > 0.999 and out["rmse"][0] < 0.05 * out["std"][0]
    assert out["r2"][1] < 0.1
    img = z.reshape(600, 5, 2, 2)  # features of any shape are flattened per state
    same = linear_probe(img[:400], y[:400], img[400:], y[400:], ridge=1e-3)
    np.testing.assert_allclose(same["r2"], out["r2"])
    with pytest.raises(ValueError, match="must agree"):
        linear_probe(z[:400], y[:300], z[400:], y[400:])
    with pytest.raises(ValueError, match="finite"):
        linear_probe(np.full((4, 2), np.nan), y[:4], z[:4, :2], y[:4])
