"""The importer against the official nuScenes devkit on the same schema-exact fixture: ego
poses, vehicle boxes, lane centrelines, the map's class masks and the prediction
rasteriser's static layers. Skipped where ``nuscenes-devkit`` is not installed (it needs
NumPy 1.x, so it is no dependency of the package; install it beside the oldest releases)."""

import numpy as np
import pytest

devkit = pytest.importorskip("nuscenes", reason="nuscenes-devkit is not installed "
                             "(pip install nuscenes-devkit, with numpy<2)")

from nuscenes.eval.common.utils import quaternion_yaw  # noqa: E402
from nuscenes.map_expansion import arcline_path_utils  # noqa: E402
from nuscenes.map_expansion.map_api import NuScenesMap  # noqa: E402
from nuscenes.nuscenes import NuScenes  # noqa: E402
from nuscenes.prediction import PredictHelper  # noqa: E402
from nuscenes.prediction.input_representation import agents, static_layers  # noqa: E402
from pyquaternion import Quaternion  # noqa: E402

from minimanc import world  # noqa: E402
from minimanc.world.history import History, history_of  # noqa: E402
from minimanc.world.lanes import class_grid  # noqa: E402
from minimanc.world.nuscenes import MapExpansion, import_nuscenes  # noqa: E402
from minimanc.world.nuscenes import sample as made_up  # noqa: E402
from minimanc.world.raster import VEHICLE  # noqa: E402

RES = 0.25


@pytest.fixture(scope="module")
def both(tmp_path_factory):
    root = tmp_path_factory.mktemp("nuscenes-devkit")
    made_up.write_sample(root)
    import_nuscenes(root, made_up.VERSION, root / "out.npz")
    nusc = NuScenes(version=made_up.VERSION, dataroot=str(root), verbose=False)
    return root, nusc, world.load(root / "out.npz")


def wrap(a):
    return (np.asarray(a) + np.pi) % (2 * np.pi) - np.pi


def test_ego_poses_and_boxes_match_the_devkit(both):
    _, nusc, ds = both
    scenes = {s["name"]: s for s in nusc.scene}
    for i, tags in enumerate(ds.tags):
        tok, poses, boxes = scenes[tags["scene"]]["first_sample_token"], [], []
        while tok and len(poses) < 40:
            sample = nusc.get("sample", tok)
            sd = nusc.get("sample_data", sample["data"]["LIDAR_TOP"])
            ep = nusc.get("ego_pose", sd["ego_pose_token"])
            poses.append([*ep["translation"][:2], quaternion_yaw(Quaternion(ep["rotation"]))])
            for a in sample["anns"]:
                ann = nusc.get("sample_annotation", a)
                if ann["category_name"].startswith("vehicle."):
                    boxes.append([len(poses) - 1, *ann["translation"][:2],
                                  quaternion_yaw(Quaternion(ann["rotation"])),
                                  ann["size"][1], ann["size"][0]])
            tok = sample["next"]
        poses = np.array(poses)
        assert np.abs(ds.ego[i, :, :2] - poses[:, :2]).max() < 1e-3
        assert np.abs(wrap(ds.ego[i, :, 2] - poses[:, 2])).max() < 1e-5
        ours = sorted([k, *ds.ado[i, k, a]] for k in range(40)
                      for a in np.flatnonzero(ds.ado_valid[i, k]))
        theirs = sorted(boxes)
        assert len(ours) == len(theirs) > 0
        d = np.abs(np.array(ours) - np.array(theirs))
        d[:, 3] = np.abs(wrap(d[:, 3]))
        assert d.max() < 1e-3


def test_lane_centrelines_match_discretize_lane(both):
    root, _, _ = both
    nmap = NuScenesMap(dataroot=str(root), map_name=made_up.LOCATION)
    m = MapExpansion(root, made_up.LOCATION)
    assert set(m.lane_tokens) == {r["token"] for r in nmap.lane + nmap.lane_connector}
    for tok, ours in zip(m.lane_tokens, m.centre, strict=True):
        theirs = np.array(arcline_path_utils.discretize_lane(nmap.arcline_path_3[tok], 1.0))
        keep = np.r_[True, np.hypot(*np.diff(theirs[:, :2], axis=0).T) > 1e-9]
        theirs = theirs[keep]  # the devkit repeats the point where two paths join
        assert ours.shape == theirs.shape
        assert np.abs(ours[:, :2] - theirs[:, :2]).max() < 1e-6
        assert np.abs(wrap(ours[:, 2] - theirs[:, 2])).max() < 1e-6
    succ = dict(zip(m.lane_tokens, m.successors, strict=True))
    for tok in m.lane_tokens:
        assert sorted(m.lane_tokens[j] for j in succ[tok]) == \
            sorted(nmap.get_outgoing_lane_ids(tok))


def test_class_grid_matches_the_devkit_map_masks(both):
    root, _, ds = both
    nmap = NuScenesMap(dataroot=str(root), map_name=made_up.LOCATION)
    cx, cy, size = made_up.CENTRE[0] + 20.0, made_up.CENTRE[1] - 30.0, 100.0
    n = int(size / RES)
    drivable, crossing, walkway = nmap.get_map_mask(
        (cx, cy, size, size), 0.0, ["drivable_area", "ped_crossing", "walkway"],
        canvas_size=(n, n)).astype(bool)  # row k: y = cy - size / 2 + RES (k + 1/2)
    want = np.where(crossing, 2, np.where(drivable, 1, np.where(walkway, 3, 0)))
    grid, origin, res = class_grid(ds.maps[0], RES)
    c = cx - size / 2 + RES * (np.arange(n) + 0.5)
    r = cy - size / 2 + RES * (np.arange(n) + 0.5)
    ours = grid[np.floor((r - origin[1]) / res).astype(int)[:, None],
                np.floor((c - origin[0]) / res).astype(int)[None, :]]
    assert set(np.unique(want)) == {0, 1, 2, 3}
    assert (ours == want).mean() > 0.99  # the cells cut by an edge may differ


def test_static_raster_matches_the_prediction_rasteriser(both):
    """The devkit's agent-centred static layers (drivable area, crossing, walkway; lanes
    drawn on top) against the class grid behind the world's raster, on the pixels the lanes
    leave free. The devkit paints walkways over the drivable area; the importer draws them
    under it, so a devkit walkway pixel on the drivable area counts as agreeing."""
    root, nusc, ds = both
    ras = static_layers.StaticLayerRasterizer(PredictHelper(nusc), resolution=RES)
    grid, origin, res = class_grid(ds.maps[0], RES)
    colours = {(255, 255, 255): 1, (119, 136, 153): 2, (0, 0, 255): 3, (0, 0, 0): 0}
    for k in (0, 20, 26):
        sample = made_up.token("scene-0061", "sample", k)
        inst = made_up.token("scene-0061", "instance", "car_lead")
        img = ras.make_representation(inst, sample)
        ann = next(nusc.get("sample_annotation", a) for a in nusc.get("sample", sample)["anns"]
                   if nusc.get("sample_annotation", a)["instance_token"] == inst)
        x, y = ann["translation"][:2]
        yaw = quaternion_yaw(Quaternion(ann["rotation"]))
        rows, cols = np.mgrid[0:img.shape[0], 0:img.shape[1]]
        fwd = (ras.meters_ahead / RES - rows - 0.5) * RES  # heading up, the agent's left left
        left = (ras.meters_left / RES - cols - 0.5) * RES
        wx = x + fwd * np.cos(yaw) - left * np.sin(yaw)
        wy = y + fwd * np.sin(yaw) + left * np.cos(yaw)
        ours = grid[np.floor((wy - origin[1]) / res).astype(int),
                    np.floor((wx - origin[0]) / res).astype(int)]
        lab = np.full(img.shape[:2], -1)
        for rgb, v in colours.items():
            lab[np.all(img == rgb, axis=-1)] = v
        free = lab >= 0
        assert free.mean() > 0.8
        agree = (lab == ours) | ((lab == 3) & (ours == 1))
        assert agree[free].mean() > 0.985, k


def vehicle_white(category: str) -> tuple[int, int, int]:
    """The devkit's colour map for the mask comparison: vehicles white, others blue (the
    devkit fades any colour, black too, to a grey of value 0.4, so they cannot be hidden)."""
    return (255, 255, 255) if category.startswith("vehicle.") else (0, 0, 255)


def grow(mask, px):
    """``mask`` dilated by ``px`` pixels (the 8-neighbourhood, ``px`` times)."""
    out = mask.copy()
    for _ in range(px):
        p = np.pad(out, 1)
        out = np.zeros_like(out)
        for dr in (-1, 0, 1):
            for dc in (-1, 0, 1):
                out |= p[1 + dr:p.shape[0] - 1 + dr, 1 + dc:p.shape[1] - 1 + dc]
    return out


def test_faded_history_boxes_match_agent_boxes_with_faded_history(both):
    """The ados drawn with faded history (``RasterConfig(history=4)``: the boxes of the last
    2 s at 2 Hz) against the devkit's ``agents.AgentBoxesWithFadedHistory(seconds_of_history=2)``,
    both centred on the leading car's annotated pose, heading up, 0.25 m/px, 40 m ahead, 10 m
    behind, 25 m to each side. Compared: the union of the vehicles' boxes (current and past),
    as masks. The devkit fills corners truncated to whole pixels (``cv2.fillPoly``) and then
    rotates the image with bilinear interpolation (``cv2.warpAffine``), the world tests pixel
    centres against the exact box: masks may differ on a box's rim, so every pixel of one
    must lie within 2 px (0.5 m) of the other (measured: within 1 px at keyframes 2 and 12,
    11 px of 436 at 1-2 px at keyframe 26, mid-turn), and the masks overlap by IoU > 0.7
    (a one-pixel rim is a large share of a 0.6 m wide bicycle at 0.25 m/px). The
    devkit draws no ego (it has no annotation), so the ego's own past is left out here; the
    fade differs by design (devkit: HSV value 0.4 → 1 per agent; world: ``1 − j/(H+1)``)
    and is not compared; the current box is at full colour in both (checked at the centre
    agent)."""
    _, nusc, ds = both
    i = next(i for i, t in enumerate(ds.tags) if t["scene"] == "scene-0061")
    helper = PredictHelper(nusc)
    ras = agents.AgentBoxesWithFadedHistory(helper, seconds_of_history=2.0, resolution=RES,
                                     color_mapping=vehicle_white)
    cfg = world.RasterConfig(size=200, history=4, draw_lanes=False, draw_walkways=False,
                             draw_crossings=False)
    inst = made_up.token("scene-0061", "instance", "car_lead")
    past = history_of(ds.ego[i], ds.ado[i], ds.ado_valid[i], 4)
    for k in (2, 12, 26):
        sample = made_up.token("scene-0061", "sample", k)
        ann = helper.get_sample_annotation(inst, sample)
        pose = [*ann["translation"][:2], quaternion_yaw(Quaternion(ann["rotation"]))]
        theirs_img = ras.make_representation(inst, sample)
        theirs = theirs_img[..., 0] > 0  # white, grey or the centre agent's red
        h = History(past.ego[k:k + 1], np.zeros((1, 4), bool), past.ado[k:k + 1],
                    past.ado_valid[k:k + 1])
        img = world.rasterize(ds.maps[i], pose, ds.ado[i, k], ds.ado_valid[i, k], cfg,
                              draw_ego=False, history=h).astype(int)
        ours = (img[..., 0] > 0) & (img[..., 0] == img[..., 1]) & (img[..., 2] == 0)
        assert theirs_img.shape[:2] == ours.shape == (200, 200)
        assert theirs.sum() > 200, k  # several boxes in view
        assert not (ours & ~grow(theirs, 2)).any(), k
        assert not (theirs & ~grow(ours, 2)).any(), k
        iou = (ours & theirs).sum() / (ours | theirs).sum()
        assert iou > 0.7, (k, iou)  # measured 0.94, 0.98, 0.77
        # the current box is drawn at full colour in both (the devkit's centre agent red)
        r, c = int(cfg.metres_ahead / RES), int(cfg.metres_side / RES)
        assert tuple(img[r, c]) == VEHICLE and tuple(theirs_img[r, c]) == \
            (255, 0, 0), k
