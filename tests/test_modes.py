"""Mutual information between vAGN's q-states and the human's driving modes."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from minimanc import world
from minimanc.metrics import modes


@pytest.fixture(scope="module")
def ds():
    return world.generate(12, seed=3, raster=world.RasterConfig(size=16), workers=1)


def test_modes_agree_with_the_scene_tags_the_generator_recorded(ds):
    labels = modes.human_modes(ds)
    assert labels.shape == (12, ds.ego.shape[1])
    for i, tags in enumerate(ds.tags):
        assert np.sum(labels[i] == modes.MODES.index("yield")) == tags["yield_steps"]
        assert np.sum(labels[i] == modes.MODES.index("follow")) == tags["follow_steps"]
        on_junction = np.isin(labels[i], [modes.MODES.index("junction"),
                                           modes.MODES.index("roundabout")])
        if not (tags["has_junction"] or tags["has_roundabout"]):
            assert not on_junction.any()
        if tags["kind"] != "roundabout":
            assert not np.any(labels[i] == modes.MODES.index("roundabout"))


def test_a_dataset_from_elsewhere_is_refused(ds):
    bad = ds.subset(slice(0, 2))
    bad.ego[0, 5, 0] += 1.0
    with pytest.raises(ValueError, match="does not regenerate"):
        modes.scene_modes(bad, 0)


def test_entropy_and_mi_on_literal_cases():
    assert modes.entropy([0, 1, 0, 1]) == pytest.approx(1.0)
    assert modes.entropy([2, 2, 2]) == 0.0
    assert modes.mutual_information([0, 1, 0, 1], [1, 0, 1, 0]) == pytest.approx(1.0)
    assert modes.mutual_information([0, 0, 1, 1], [0, 1, 0, 1]) == pytest.approx(0.0)
    with pytest.raises(ValueError, match="same shape"):
        modes.mutual_information([0, 1], [0, 1, 1])
    with pytest.raises(ValueError, match="integer"):
        modes.mutual_information([0.5, 1.0], [0, 1])


@given(st.lists(st.integers(0, 4), min_size=1, max_size=60),
       st.lists(st.integers(0, 3), min_size=60, max_size=60))
def test_mi_is_bounded_by_both_entropies_and_symmetric(a, b):
    b = b[:len(a)]
    mi = modes.mutual_information(a, b)
    assert -1e-12 <= mi <= min(modes.entropy(a), modes.entropy(b)) + 1e-9
    assert mi == pytest.approx(modes.mutual_information(b, a), abs=1e-9)


def _one_hot(states, n):
    return np.eye(n)[states]


def test_a_q_that_tracks_the_mode_carries_its_information():
    rng = np.random.default_rng(0)
    labels = rng.integers(0, 4, size=(30, 40))
    out = modes.mode_information(_one_hot(labels, 4), labels, n_shuffles=50)
    assert out["mi_bits"] == pytest.approx(out["mode_entropy_bits"])
    assert out["excess_bits"] > 1.5 and out["p_value"] == pytest.approx(1 / 51)
    assert out["states_used"] == 4


def test_a_clock_carries_no_information_about_the_scene():
    rng = np.random.default_rng(1)
    # modes that last (runs of 8 steps), a q cycling with period 3 in every scene alike
    labels = np.repeat(rng.integers(0, 3, size=(40, 5)), 8, axis=1)
    clock = np.tile(np.arange(40) % 3, (40, 1))
    out = modes.mode_information(_one_hot(clock, 3), labels, n_shuffles=100)
    assert out["switch_rate"] == 1.0 and out["q_change"] == pytest.approx(1.0)
    assert out["p_value"] > 0.05
    assert abs(out["excess_bits"]) < 0.05


def test_bad_shapes_are_refused():
    with pytest.raises(ValueError, match="shape"):
        modes.mode_information(np.ones((2, 3, 4)) / 4, np.zeros((2, 4), dtype=int))
    with pytest.raises(ValueError, match="2 scenes"):
        modes.mode_information(np.ones((1, 3, 4)) / 4, np.zeros((1, 3), dtype=int))
    with pytest.raises(ValueError, match="finite"):
        modes.mode_information(np.full((2, 3, 4), np.nan), np.zeros((2, 3), dtype=int))
