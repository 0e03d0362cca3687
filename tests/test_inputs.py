"""Tests for minimanc.inputs (chapter 8): what each model sees, from the log and the closed loop."""

from __future__ import annotations

import numpy as np
import pytest

from minimanc import inputs, models, world


@pytest.fixture(scope="module")
def ds():
    return world.generate(3, seed=0, raster=world.RasterConfig(size=32))


def test_visibility_table():
    for name in models.names():
        spec = models.get(name)
        paper, parity = inputs.visible(spec, "paper"), inputs.visible(spec, "parity")
        assert set(paper) <= set(parity)
        assert "bev" in paper
        if name in ("manc", "dmp_only"):
            # the DMP tracks the moving lane target from the current motion, never the goal pose
            assert paper == parity == ("bev", "lane_target", "motion")
        else:
            assert "goal" in paper and "lane_target" not in paper and "motion" not in paper
            assert {"lane_target", "motion"} <= set(parity)
        assert ("goal_bev" in paper) == (name == "rvs_g")


def test_bad_names_raise():
    with pytest.raises(ValueError, match="setting"):
        inputs.visible(models.get("cnn"), "oracle")
    with pytest.raises(ValueError, match="model must be a model spec"):
        inputs.visible("cnn", "paper")  # a name: the caller looks its spec up (models.get)
    with pytest.raises(ValueError, match="goal"):
        inputs.select({"bev": np.zeros((1, 4, 4, 3))}, models.get("cnn"))


def test_numeric_features_size_and_scale():
    rng = np.random.default_rng(0)
    obs = {"goal": rng.normal(size=(4, 3)) * 50, "lane_target": rng.normal(size=(4, 10, 2)) * 40,
           "motion": rng.normal(size=(4, 2))}
    for name in models.names():
        for setting in inputs.SETTINGS:
            f = inputs.numeric_features(obs, models.get(name), setting)
            n = inputs.numeric_size(models.get(name), setting)
            if n == 0:
                assert f is None
            else:
                assert f.shape == (4, n)
    f = inputs.numeric_features(obs, models.get("cnn"), "paper")
    np.testing.assert_allclose(f, obs["goal"] / np.array(inputs.GOAL_SCALE), rtol=1e-6)


def test_from_dataset_shapes_and_values(ds):
    s = np.array([0, 1, 2, 2])
    t = np.array([0, 5, 39, 1])
    obs = inputs.from_dataset(ds, s, t)
    assert set(obs) == {"bev", "goal", "lane_target", "motion"}
    assert obs["bev"].shape == (4, 32, 32, 3) and obs["bev"].dtype == np.float32
    assert 0.0 <= obs["bev"].min() and obs["bev"].max() <= 1.0
    np.testing.assert_array_equal(obs["bev"], ds.bev[s, t] / np.float32(255))
    np.testing.assert_array_equal(obs["goal"], ds.goal[s, t])
    np.testing.assert_array_equal(obs["lane_target"], ds.lane_target[s, t])
    # motion: the previous control, never the current one (no look into the future)
    np.testing.assert_array_equal(obs["motion"][1:3], ds.controls[[1, 2], [4, 38]])
    np.testing.assert_array_equal(obs["motion"][3], ds.controls[2, 0])
    # t = 0: the initial motion, speed only
    np.testing.assert_array_equal(obs["motion"][0], [ds.controls[0, 0, 0], 0.0])
    np.testing.assert_array_equal(inputs.initial_motion(ds)[:, 1], 0.0)


def test_from_dataset_respects_the_model(ds):
    assert set(inputs.from_dataset(ds, 0, 3, "paper", model=models.get("cnn"))) == {"bev", "goal"}
    rvs = inputs.from_dataset(ds, [0, 1], [3, 3], "paper", model=models.get("rvs_g"))
    np.testing.assert_array_equal(rvs["goal_bev"], ds.goal_bev[[0, 1]] / np.float32(255))
    assert set(inputs.from_dataset(ds, 0, 3, "parity", model=models.get("manc"))) == {
        "bev", "lane_target", "motion"}


def test_from_dataset_bad_indices(ds):
    with pytest.raises(ValueError, match="scene_idx"):
        inputs.from_dataset(ds, 3, 0)
    with pytest.raises(ValueError, match="t_idx"):
        inputs.from_dataset(ds, 0, 40)
    with pytest.raises(ValueError, match="same length"):
        inputs.from_dataset(ds, [0, 1], [0, 1, 2])
    one = inputs.from_dataset(ds, 1, [3, 4])  # one scene, two times
    np.testing.assert_array_equal(one["goal"], ds.goal[1, 3:5])
    with pytest.raises(ValueError, match="setting"):
        inputs.from_dataset(ds, 0, 0, setting="cheat")


def test_from_state_at_the_logged_pose_reproduces_the_log(ds):
    """The closed loop at the human's own pose must see exactly what the log shows."""
    t = 7
    s = np.arange(3)
    goal_world = ds.ego[:, -1]
    obs = inputs.from_state(ds.maps, ds.ego[s, t], ds.ado[s, t], ds.ado_valid[s, t], goal_world,
                            ds.raster, "parity", motion=ds.controls[s, t - 1],
                            model=models.get("rvs_g"))
    ref = inputs.from_dataset(ds, s, np.full(3, t), "parity", model=models.get("rvs_g"))
    assert set(obs) == set(ref)
    np.testing.assert_array_equal(obs["bev"], ref["bev"])
    np.testing.assert_allclose(obs["lane_target"], ref["lane_target"], atol=1e-3)
    np.testing.assert_allclose(obs["goal"][:, :2], ref["goal"][:, :2], atol=1e-3)
    np.testing.assert_allclose(obs["motion"], ref["motion"])
    np.testing.assert_array_equal(obs["goal_bev"], ref["goal_bev"])


def test_lane_target_depends_on_the_pose_not_the_time(ds):
    """Same pose at two different times → the same lane target (no human-time indexing)."""
    pose = ds.ego[0, 10]
    a = inputs.from_state(ds.maps[0], pose[None], None, None, ds.ego[0, -1][None], ds.raster,
                          motion=np.zeros((1, 2)))
    b = inputs.from_state(ds.maps[0], pose[None], None, None, ds.ego[0, -1][None], ds.raster,
                          motion=np.full((1, 2), 9.0))
    np.testing.assert_array_equal(a["lane_target"], b["lane_target"])
    gaps = np.linalg.norm(np.diff(a["lane_target"][0], axis=0), axis=-1)
    assert np.all(gaps <= 4.0 + 1e-3) and np.all(gaps > 2.0)  # 4 m of arc between points


def test_from_state_bad_input(ds):
    pose = ds.ego[0, :1]
    with pytest.raises(ValueError, match="motion"):
        inputs.from_state(ds.maps[0], pose, None, None, ds.ego[0, -1][None], ds.raster,
                          motion=np.zeros((2, 2)))
    with pytest.raises(ValueError, match="ego_poses"):
        inputs.from_state(ds.maps[0], pose[0], None, None, ds.ego[0, -1][None], ds.raster,
                          motion=np.zeros((1, 2)))
    with pytest.raises(ValueError, match="goal_world"):
        inputs.from_state(ds.maps[0], pose, None, None, ds.ego[0, -1], ds.raster,
                          motion=np.zeros((1, 2)))
