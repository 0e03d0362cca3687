"""Chapter 7 — the bird's-eye-view (BEV) rasteriser: ego-centric, heading up, two encodings.

The nuScenes devkit's prediction raster is 500 x 500 px at 0.1 m/px: 40 m
ahead, 10 m behind and 25 m to each side of the agent, which sits at row 400,
column 250 facing up. :class:`RasterConfig` keeps those *proportions* and
scales the image down (64 x 64 by default: 0.78 m/px) for CPU training; any
other view (a longer, narrower corridor: :meth:`RasterConfig.from_extent`) has
``size`` rows and ``cols`` columns.

One rasteriser draws every frame, in one of two **encodings**
(``RasterConfig.encoding``):

* ``"rgb"`` — the devkit's look, for people and for the paper's setting: the layers
  below, each overwriting the previous where it draws, in one uint8 RGB image;
* ``"channels"`` — for a learner: one binary plane per layer (the field's practice:
  Roach's policy reads 15 binary channels, l5kit one channel per history frame; the
  faded RGB image is for display, :func:`~minimanc.world.encodings.to_rgb`), and the
  ego's **route** ahead
  (``route=True``), which at a junction says which of the lanes the ego takes. Each
  past step's vehicles have their own plane, so motion is not blended away. Stored
  bit-packed (:func:`pack`); :mod:`minimanc.world.encodings` reads them back.

============= =============== ================================ ==============================
layer         colour (RGB)    channel(s)                       source
============= =============== ================================ ==============================
background    (0, 0, 0)
walkway       (0, 0, 255)     ``walkway``                      map class grid
drivable area (255, 255, 255) ``drivable`` (crossings in)      map class grid
ped crossing  (119, 136, 153) ``crossing``                     map class grid
lanes         HSV hue by yaw  ``lane_same``, ``lane_opposite`` centrelines; within 90° of the
                                                               ego's heading = cyan, else red
route         —               ``route``                        the route on from the ego's
                                                               projection, :data:`ROUTE_WIDTH`
faded history colours × fade  ``ego_t-j``, ``vehicles_t-j``    past boxes, ego frame at t
ado vehicles  (255, 255, 0)   ``vehicles``                     oriented boxes
ego           (255, 0, 0)     ``ego``                          4.727 m x 1.907 m at the pose
============= =============== ================================ ==============================

A layer switched off (``draw_lanes``, ``draw_crossings``, ``draw_walkways``) has no
plane; :attr:`RasterConfig.channel_names` lists the planes in order.

Pixel convention: the pixel containing the ego-frame point ``(x, y)`` (x
forward, y left) is ``row = floor((metres_ahead - x) / res_row)``,
``col = floor((metres_side - y) / res_col)`` — see
:meth:`RasterConfig.ego_to_pixel`. Every frame is rendered by inverse mapping:
each pixel centre is moved to the world, looked up in the map's class grid
(:func:`minimanc.world.lanes.class_grid`) and tested against the boxes —
vectorised NumPy, no Python loop over pixels, any ego pose. Both encodings share
every step; they differ only in what a step writes.
"""

from __future__ import annotations

import functools
from dataclasses import asdict, dataclass

import numpy as np

from minimanc.checks import check_int
from minimanc.world.geometry import EGO_LENGTH, EGO_WIDTH, wrap_angle
from minimanc.world.history import MAX_HISTORY, History, fade
from minimanc.world.lanes import (
    CLASS_CROSSING,
    CLASS_DRIVABLE,
    CLASS_NONE,
    CLASS_WALKWAY,
    Map,
    class_grid,
)
from minimanc.world.maps import project_to_route

BACKGROUND = (0, 0, 0)
DRIVABLE = (255, 255, 255)
PED_CROSSING = (119, 136, 153)
WALKWAY = (0, 0, 255)
VEHICLE = (255, 255, 0)
EGO = (255, 0, 0)
ROUTE = (0, 170, 0)  # display only (encodings.to_rgb): the RGB encoding draws no route
SAME_LANE = (0, 255, 255)
OPPOSITE_LANE = (255, 0, 0)

ENCODINGS = ("rgb", "channels")
"""The two encodings of the one rasteriser."""
ROUTE_WIDTH = 2.0
"""Width (m) of the band the route is drawn as (about a car's width)."""


def channel_names(draw_crossings: bool = True, draw_walkways: bool = True,
                  draw_lanes: bool = True, route: bool = False,
                  history: int = 0) -> tuple[str, ...]:
    """The planes of the ``"channels"`` encoding, in order: the map's (``drivable``, then
    ``crossing``, ``walkway``, ``lane_same``, ``lane_opposite``, ``route`` where drawn), the
    ego's (``ego``, ``ego_t-1`` … ``ego_t-H``) and the other vehicles' (``vehicles``,
    ``vehicles_t-1`` … ``vehicles_t-H``), ``H = history``."""
    names = ["drivable"]
    names += ["crossing"] * bool(draw_crossings) + ["walkway"] * bool(draw_walkways)
    names += ["lane_same", "lane_opposite"] * bool(draw_lanes) + ["route"] * bool(route)
    for who in ("ego", "vehicles"):
        names += [who] + [f"{who}_t-{j}" for j in range(1, history + 1)]
    return tuple(names)


def pack(img: np.ndarray) -> np.ndarray:
    """Binary planes ``(..., C)`` packed in uint8 ``(..., ceil(C / 8))``, plane ``k`` in bit
    ``k % 8`` of byte ``k // 8``: ``np.packbits(img, axis=-1, bitorder="little")``."""
    bits = np.asarray(img) != 0
    out = np.zeros((*bits.shape[:-1], -(-bits.shape[-1] // 8)), dtype=np.uint8)
    for k in range(bits.shape[-1]):
        out[..., k // 8] |= bits[..., k].view(np.uint8) << np.uint8(k % 8)
    return out


@dataclass(frozen=True)
class RasterConfig:
    """Raster geometry, layers and encoding. Defaults: nuScenes proportions at 64 x 64 px, RGB.

    ``size`` rows cover ``metres_ahead + metres_behind`` and ``cols`` columns (default
    ``size``: square) cover ``2 * metres_side`` (defaults: 0.78 m pixels; the devkit's
    0.1 m/px is ``size=500``, the authors' 0.2 m/px ``size=250``; a corridor is
    :meth:`from_extent`). Lane centrelines are ``lane_width_m`` wide (devkit: 0.5 m), at
    least one pixel; ``draw_lanes``, ``draw_walkways`` and ``draw_crossings`` switch those
    layers; ``ego_length`` and ``ego_width`` (m) size the ego's box. ``history`` past steps
    are drawn (:mod:`minimanc.world.history`; 0, the authors' environment, draws none):
    faded boxes under the current ones in RGB, one plane per step in channels.
    ``encoding`` is ``"rgb"`` or ``"channels"`` (:data:`ENCODINGS`); ``route`` draws the
    ego's route ahead (channels only).
    """

    size: int = 64
    metres_ahead: float = 40.0
    metres_behind: float = 10.0
    metres_side: float = 25.0
    lane_width_m: float = 0.5
    draw_lanes: bool = True
    draw_walkways: bool = True
    draw_crossings: bool = True
    ego_length: float = EGO_LENGTH
    ego_width: float = EGO_WIDTH
    history: int = 0
    cols: int | None = None
    encoding: str = "rgb"
    route: bool = False

    def __post_init__(self) -> None:
        check_int("size", self.size, 8)
        if self.cols is not None:
            check_int("cols", self.cols, 8)
        check_int("history", self.history, 0, MAX_HISTORY)
        for name in ("metres_ahead", "metres_side", "ego_length", "ego_width",
                     "lane_width_m"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be positive and finite, got {v!r}")
        if not (np.isfinite(self.metres_behind) and self.metres_behind >= 0):
            raise ValueError(f"metres_behind must be >= 0, got {self.metres_behind!r}")
        if self.encoding not in ENCODINGS:
            raise ValueError(f"encoding must be one of {ENCODINGS}, got {self.encoding!r}")
        for name in ("draw_lanes", "draw_walkways", "draw_crossings", "route"):
            if not isinstance(getattr(self, name), bool | np.bool_):
                raise ValueError(f"{name} must be True or False, got {getattr(self, name)!r}")
        if self.route and self.encoding != "channels":
            raise ValueError("route=True needs encoding='channels' (the RGB raster keeps the "
                             "devkit's layers and draws no route)")

    @classmethod
    def from_extent(cls, metres_ahead: float, metres_side: float, resolution: float,
                    metres_behind: float = 10.0, **fields) -> RasterConfig:
        """The view ``metres_ahead`` ahead, ``metres_behind`` behind and ``metres_side`` to
        each side at about ``resolution`` m/px: ``size = round((ahead + behind) /
        resolution)`` rows, ``cols = round(2 side / resolution)`` columns (the pixels are
        exactly square when the extents are multiples of the resolution); ``fields`` are
        the other fields."""
        if not (np.isfinite(resolution) and resolution > 0):
            raise ValueError(f"resolution must be positive and finite, got {resolution!r}")
        size = int(round((metres_ahead + metres_behind) / resolution))
        cols = int(round(2.0 * metres_side / resolution))
        return cls(size=size, cols=cols, metres_ahead=metres_ahead,
                   metres_behind=metres_behind, metres_side=metres_side, **fields)

    def as_meta(self) -> dict:
        """The config as a dataset's metadata stores it: every field, those added after the
        format's first version (``history``, ``cols``, ``encoding``, ``route``) only when
        they differ from their defaults (so the metadata and checksums of a dataset drawn
        without them are those of the format before them)."""
        d = asdict(self)
        for name, default in (("history", 0), ("cols", None), ("encoding", "rgb"),
                              ("route", False)):
            if d[name] == default:
                del d[name]
        return d

    @property
    def width(self) -> int:
        """Columns of the image."""
        return self.size if self.cols is None else self.cols

    @property
    def channel_names(self) -> tuple[str, ...]:
        """The planes a learner reads: ``("red", "green", "blue")`` in RGB, else
        :func:`channel_names` of this config's layers."""
        if self.encoding == "rgb":
            return ("red", "green", "blue")
        return channel_names(self.draw_crossings, self.draw_walkways, self.draw_lanes,
                             self.route, self.history)

    @property
    def input_shape(self) -> tuple[int, int, int]:
        """``(H, W, C)`` of the planes a learner reads (:func:`to_input`)."""
        return (self.size, self.width, len(self.channel_names))

    @property
    def shape(self) -> tuple[int, int, int]:
        """``(H, W, bytes)`` of one stored frame: RGB ``(H, W, 3)``; channels bit-packed,
        ``ceil(C / 8)`` bytes per pixel (:func:`pack`)."""
        if self.encoding == "rgb":
            return (self.size, self.width, 3)
        return (self.size, self.width, -(-len(self.channel_names) // 8))

    @property
    def res_row(self) -> float:
        """Metres per pixel along the ego's x axis (rows)."""
        return (self.metres_ahead + self.metres_behind) / self.size

    @property
    def res_col(self) -> float:
        """Metres per pixel along the ego's y axis (columns)."""
        return 2.0 * self.metres_side / self.width

    @property
    def resolution(self) -> float:
        """Metres per pixel (the finer of the two axes)."""
        return min(self.res_row, self.res_col)

    @property
    def ego_pixel(self) -> tuple[int, int]:
        """(row, col) of the pixel holding the ego's centre."""
        r, c = self.ego_to_pixel(np.zeros(2))
        return int(r), int(c)

    def ego_to_pixel(self, points_ego: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(row, col) integer pixel indices of ego-frame points ``(..., 2)`` (may be outside)."""
        p = np.asarray(points_ego, dtype=np.float64)
        row = np.floor((self.metres_ahead - p[..., 0]) / self.res_row).astype(np.int64)
        col = np.floor((self.metres_side - p[..., 1]) / self.res_col).astype(np.int64)
        return row, col

    def pixel_centres(self) -> tuple[np.ndarray, np.ndarray]:
        """Ego-frame coordinates ``(x (H, W), y (H, W))`` of the pixel centres."""
        return _pixel_centres(self)

    def grid_res(self) -> float:
        """Resolution of the map class grid sampled by this raster (m/cell)."""
        return float(min(0.25, self.resolution / 2.0))


@functools.lru_cache(maxsize=16)
def _pixel_centres(cfg: RasterConfig) -> tuple[np.ndarray, np.ndarray]:
    x = cfg.metres_ahead - (np.arange(cfg.size, dtype=np.float64) + 0.5) * cfg.res_row
    y = cfg.metres_side - (np.arange(cfg.width, dtype=np.float64) + 0.5) * cfg.res_col
    X, Y = np.meshgrid(x, y, indexing="ij")
    return X, Y


@functools.lru_cache(maxsize=16)
def _ego_mask(cfg: RasterConfig) -> np.ndarray:
    X, Y = _pixel_centres(cfg)
    return (np.abs(X) <= cfg.ego_length / 2) & (np.abs(Y) <= cfg.ego_width / 2)


def box_mask(px_x: np.ndarray, px_y: np.ndarray, box: np.ndarray) -> np.ndarray:
    """Pixels whose centres ``(px_x, px_y)`` lie inside the oriented box ``[x, y, yaw, l, w]``.

    All in one frame (here the ego frame). The pixel centre is rotated into
    the box's own frame, ``u = R(-yaw) (p - c)``, and tested against the half
    length and half width. ``box`` may be ``(A, 5)``: the result is then
    ``(A, H, W)``.
    """
    b = np.asarray(box, dtype=np.float64)
    single = b.ndim == 1
    b = np.atleast_2d(b)
    c = np.cos(b[:, 2])[:, None, None]
    s = np.sin(b[:, 2])[:, None, None]
    dx = px_x[None] - b[:, 0, None, None]
    dy = px_y[None] - b[:, 1, None, None]
    u = c * dx + s * dy
    v = -s * dx + c * dy
    m = (np.abs(u) <= b[:, 3, None, None] / 2) & (np.abs(v) <= b[:, 4, None, None] / 2)
    return m[0] if single else m


def hue_colours(relative_yaw: np.ndarray) -> np.ndarray:
    """nuScenes lane colour for lane headings relative to the agent: uint8 ``(..., 3)``.

    ``hue = (wrap(agent_yaw - lane_yaw) + pi) / (2 pi)``, saturation = value = 1
    (the devkit's ``color_by_yaw``): 0 (same direction) is cyan, pi is red.
    ``relative_yaw`` is ``agent_yaw - lane_yaw``.
    """
    h = (wrap_angle(relative_yaw) + np.pi) / (2 * np.pi)
    h6 = h * 6.0
    i = np.floor(h6).astype(np.int64) % 6
    f = h6 - np.floor(h6)
    one, zero = np.ones_like(f), np.zeros_like(f)
    q, t = 1.0 - f, f
    r = np.choose(i, [one, q, zero, zero, t, one])
    g = np.choose(i, [t, one, one, q, zero, zero])
    b = np.choose(i, [zero, zero, t, one, one, q])
    return np.round(np.stack([r, g, b], axis=-1) * 255).astype(np.uint8)


_N_HUE = 2048
_HUE_LUT = hue_colours((np.arange(_N_HUE) + 0.5) * (2 * np.pi / _N_HUE))


@functools.lru_cache(maxsize=16)
def _class_lut(cfg: RasterConfig) -> np.ndarray:
    lut = np.zeros((256, 3), dtype=np.uint8)
    lut[CLASS_NONE] = BACKGROUND
    lut[CLASS_DRIVABLE] = DRIVABLE
    lut[CLASS_CROSSING] = PED_CROSSING if cfg.draw_crossings else DRIVABLE
    lut[CLASS_WALKWAY] = WALKWAY if cfg.draw_walkways else BACKGROUND
    return lut


def check_history(history: History | None, cfg: RasterConfig, frames: int,
                  with_ados: bool) -> History | None:
    """``history`` checked against ``cfg.history`` and the ``frames`` drawn (``None`` when the
    raster draws no history: ``cfg.history == 0``, or a frame without ados, e.g. a goal)."""
    if cfg.history == 0 or not with_ados:
        if history is not None and cfg.history == 0:
            raise ValueError("a history was given but the raster draws none (history=0)")
        return None
    if not isinstance(history, History):
        raise ValueError(f"this raster draws {cfg.history} past steps (RasterConfig.history): "
                         "pass history= the frames' past (minimanc.world.history.history_of)")
    if history.ego_valid.shape != (frames, cfg.history):
        raise ValueError(f"history must hold {frames} frames of {cfg.history} steps; got "
                         f"{history.ego_valid.shape}")
    return history


def _check_pose(ego_pose: np.ndarray) -> np.ndarray:
    pose = np.asarray(ego_pose, dtype=np.float64)
    if pose.shape != (3,) or not np.all(np.isfinite(pose)):
        raise ValueError(f"ego_pose must be 3 finite numbers [x, y, yaw], got {ego_pose!r}")
    return pose


def _box_pixels(poses: np.ndarray, fb: np.ndarray, b: np.ndarray, cfg: RasterConfig
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pixels ``(frame, row, col)`` of the world boxes ``b (N, 5)`` in the frames ``fb (N,)``
    (seen from ``poses``): every (frame, box) tested on a square crop of pixels around it."""
    H, W = cfg.size, cfg.width
    X, Y = _pixel_centres(cfg)
    cos, sin = np.cos(poses[fb, 2]), np.sin(poses[fb, 2])
    dx, dy = b[:, 0] - poses[fb, 0], b[:, 1] - poses[fb, 1]
    bx = cos * dx + sin * dy
    by = -sin * dx + cos * dy
    half = np.hypot(b[:, 3], b[:, 4]) / 2
    vis = ((bx - half < cfg.metres_ahead) & (bx + half > -cfg.metres_behind)
           & (np.abs(by) - half < cfg.metres_side))
    fb, b, bx, by, half = fb[vis], b[vis], bx[vis], by[vis], half[vis]
    if not len(fb):
        empty = np.zeros(0, dtype=np.intp)
        return empty, empty, empty
    byaw = b[:, 2] - poses[fb, 2]
    K = int(np.ceil(half.max() / cfg.resolution)) + 1
    off = np.arange(-K, K + 1)
    rc = np.floor((cfg.metres_ahead - bx) / cfg.res_row).astype(np.intp)
    cc = np.floor((cfg.metres_side - by) / cfg.res_col).astype(np.intp)
    rr = rc[:, None, None] + off[None, :, None] + 0 * off[None, None, :]
    ca = cc[:, None, None] + 0 * off[None, :, None] + off[None, None, :]
    ok = (rr >= 0) & (rr < H) & (ca >= 0) & (ca < W)
    rcl, ccl = np.clip(rr, 0, H - 1), np.clip(ca, 0, W - 1)
    px = X[rcl, ccl] - bx[:, None, None]
    py = Y[rcl, ccl] - by[:, None, None]
    c, s = np.cos(byaw)[:, None, None], np.sin(byaw)[:, None, None]
    u = c * px + s * py
    v = -s * px + c * py
    ok &= (np.abs(u) <= b[:, 3, None, None] / 2) & (np.abs(v) <= b[:, 4, None, None] / 2)
    ff = np.broadcast_to(fb[:, None, None], ok.shape)
    return ff[ok], rr[ok], ca[ok]


def _stamps(f: np.ndarray, row: np.ndarray, col: np.ndarray, width_m: float,
            cfg: RasterConfig):
    """For each pixel offset of a square stamp ``width_m`` wide (at least one pixel): the
    points ``ok`` inside the image and their ``(frame, row, col)``."""
    thick = max(int(round(width_m / cfg.resolution)), 1)
    lo = -(thick // 2)
    for dr in range(lo, lo + thick):
        for dc in range(lo, lo + thick):
            r, cc = row + dr, col + dc
            ok = (r >= 0) & (r < cfg.size) & (cc >= 0) & (cc < cfg.width)
            yield ok, f[ok], r[ok], cc[ok]


def _route_pixels(m: Map, poses: np.ndarray, frames: list[int], cfg: RasterConfig
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(frame, row, col)`` of the route's centreline from each ego's projection on it to
    the far edge of the view, sampled every half pixel (the route ends where the map's does)."""
    P = poses[frames]
    s0, _ = project_to_route(m, P[:, :2], P[:, 2])
    s0 = np.atleast_1d(s0)
    reach = float(np.hypot(max(cfg.metres_ahead, cfg.metres_behind), cfg.metres_side)) + 1.0
    ds = np.arange(0.0, reach, cfg.resolution / 2.0)
    sq = s0[:, None] + ds[None, :]
    keep, sq = sq <= m.route_s[-1], np.minimum(sq, m.route_s[-1])  # points, no headings
    px, py = (np.interp(sq, m.route_s, m.route_points[:, k]) for k in (0, 1))
    c, s = np.cos(P[:, 2])[:, None], np.sin(P[:, 2])[:, None]
    dx, dy = px - P[:, 0, None], py - P[:, 1, None]
    ex, ey = c * dx + s * dy, -s * dx + c * dy
    row = np.floor((cfg.metres_ahead - ex) / cfg.res_row).astype(np.intp)
    col = np.floor((cfg.metres_side - ey) / cfg.res_col).astype(np.intp)
    f = np.broadcast_to(np.asarray(frames)[:, None], sq.shape)
    return f[keep], row[keep], col[keep]


def _paint(img: np.ndarray, pixels: tuple[np.ndarray, ...],
           colour: np.ndarray | tuple[int, int, int], k: int | None) -> None:
    """Paint ``pixels = (frame, row, col)`` in ``colour`` (RGB, ``k`` None) or set plane ``k``."""
    img[pixels if k is None else (*pixels, k)] = colour if k is None else 1


def _render(maps: list[Map], poses: np.ndarray, ado: np.ndarray | None,
            valid: np.ndarray | None, cfg: RasterConfig, draw_ego: bool,
            history: History | None = None) -> np.ndarray:
    """Render S frames at once (checked inputs): see :func:`rasterize_batch`. Every step
    computes which pixels a layer covers; the RGB encoding paints them in the layer's
    colour (later layers over earlier ones), the channels encoding sets the layer's plane."""
    S, H, W = poses.shape[0], cfg.size, cfg.width
    rgb = cfg.encoding == "rgb"
    plane = {name: k for k, name in enumerate(cfg.channel_names)}
    X, Y = _pixel_centres(cfg)
    cos, sin = np.cos(poses[:, 2]), np.sin(poses[:, 2])
    if rgb:
        img = np.empty((S, H, W, 3), dtype=np.uint8)
        lut = _class_lut(cfg)
    else:
        img = np.zeros((S, H, W, len(plane)), dtype=np.uint8)
    groups: dict[int, tuple[Map, list[int]]] = {}
    for i, m in enumerate(maps):
        groups.setdefault(id(m), (m, []))[1].append(i)
    fs, rows, cols, qs, route = [], [], [], [], []  # every map's lanes and route, drawn below
    for m, idx_list in groups.values():
        idx = np.array(idx_list)
        # static map: pixel centres -> world -> class grid (edge cells of the grid are
        # empty, so clipping out-of-map pixels onto the edge gives the background)
        grid, origin, gres = class_grid(m, cfg.grid_res())
        gh, gw = grid.shape
        c = (cos[idx] / gres)[:, None, None]
        s = (sin[idx] / gres)[:, None, None]
        gx = c * X - s * Y + ((poses[idx, 0] - origin[0]) / gres)[:, None, None]
        gy = s * X + c * Y + ((poses[idx, 1] - origin[1]) / gres)[:, None, None]
        ix = np.clip(np.floor(gx), 0, gw - 1).astype(np.intp)
        iy = np.clip(np.floor(gy), 0, gh - 1).astype(np.intp)
        cls = np.take(grid, iy * gw + ix)
        if rgb:
            img[idx] = np.take(lut, cls, axis=0)
        else:
            img[idx, ..., plane["drivable"]] = (cls == CLASS_DRIVABLE) | (cls == CLASS_CROSSING)
            if cfg.draw_crossings:
                img[idx, ..., plane["crossing"]] = cls == CLASS_CROSSING
            if cfg.draw_walkways:
                img[idx, ..., plane["walkway"]] = cls == CLASS_WALKWAY
        # lanes: dense centreline samples scattered into the image, by relative yaw
        if cfg.draw_lanes:
            samples = m.lane_samples(float(cfg.resolution / 2.0))
            mid = (cfg.metres_ahead - cfg.metres_behind) / 2.0
            reach = max(cfg.metres_ahead + cfg.metres_behind, 2 * cfg.metres_side) / 2.0 + 1.0
            for i in idx_list:
                centre = poses[i, :2] + mid * np.array([cos[i], sin[i]])
                lp, lh = samples.near(centre, reach)  # a square around the view
                dx, dy = lp[:, 0] - poses[i, 0], lp[:, 1] - poses[i, 1]
                ex = cos[i] * dx + sin[i] * dy
                ey = -sin[i] * dx + cos[i] * dy
                rows.append(np.floor((cfg.metres_ahead - ex) / cfg.res_row))
                cols.append(np.floor((cfg.metres_side - ey) / cfg.res_col))
                # colour look-up by relative yaw (0.18° bins, within 1 unit of hue_colours)
                qs.append(np.floor(np.mod(poses[i, 2] - lh, 2 * np.pi)
                                   * (_N_HUE / (2 * np.pi))))
                fs.append(np.full(len(lp), i))
        if cfg.route:
            route.append(_route_pixels(m, poses, idx_list, cfg))
    if fs:  # the lanes of every frame at once (a frame's own order kept)
        f = np.concatenate(fs)
        row = np.concatenate(rows).astype(np.intp)
        col = np.concatenate(cols).astype(np.intp)
        q = np.minimum(np.concatenate(qs).astype(np.intp), _N_HUE - 1)
        if rgb:
            colours = _HUE_LUT[q]
        else:  # same direction: the lane's heading within 90 degrees of the ego's
            which = np.where((q < _N_HUE // 4) | (q >= 3 * _N_HUE // 4),
                             plane["lane_same"], plane["lane_opposite"])
        for ok, ff, rr, cc in _stamps(f, row, col, cfg.lane_width_m, cfg):
            if rgb:
                img[ff, rr, cc] = colours[ok]
            else:
                img[ff, rr, cc, which[ok]] = 1
    if route:
        f, row, col = (np.concatenate(part) for part in zip(*route))
        for _, ff, rr, cc in _stamps(f, row, col, ROUTE_WIDTH, cfg):
            img[ff, rr, cc, plane["route"]] = 1
    if history is not None:  # past boxes, oldest first, under the current ones
        shade = fade(history.steps)
        ego_box = np.array([cfg.ego_length, cfg.ego_width])
        for j in range(history.steps - 1, -1, -1):
            fb, kb = np.nonzero(history.ado_valid[:, j])
            _paint(img, _box_pixels(poses, fb, history.ado[fb, j, kb], cfg),
                   np.round(np.array(VEHICLE) * shade[j]), plane.get(f"vehicles_t-{j + 1}"))
            fe = np.nonzero(history.ego_valid[:, j])[0]
            boxes = np.hstack([history.ego[fe, j], np.tile(ego_box, (len(fe), 1))])
            _paint(img, _box_pixels(poses, fe, boxes, cfg),
                   np.round(np.array(EGO) * shade[j]), plane.get(f"ego_t-{j + 1}"))
    if ado is not None:
        fb, kb = np.nonzero(valid)
        _paint(img, _box_pixels(poses, fb, ado[fb, kb], cfg), VEHICLE, plane.get("vehicles"))
    if draw_ego:
        if rgb:
            img[:, _ego_mask(cfg)] = EGO
        else:
            img[:, _ego_mask(cfg), plane["ego"]] = 1
    return img if rgb else pack(img)


def rasterize(
    m: Map,
    ego_pose: np.ndarray,
    ado: np.ndarray | None = None,
    ado_valid: np.ndarray | None = None,
    cfg: RasterConfig | None = None,
    draw_ego: bool = True,
    history: History | None = None,
) -> np.ndarray:
    """Render the BEV raster seen from ``ego_pose = [x, y, yaw]`` (world frame), as stored:
    uint8 ``cfg.shape`` (RGB ``(H, W, 3)``; channels bit-packed, :func:`planes` unpacks).

    ``ado (A, 5)`` are world boxes ``[x, y, yaw, length, width]``; rows with
    ``ado_valid`` False are skipped. Any pose works (the closed loop renders
    from the policy's own pose). ``history``: the frame's past (a :class:`History` of
    one frame), required when ``cfg.history > 0`` and ados are drawn.
    """
    cfg = cfg or RasterConfig()
    pose = _check_pose(ego_pose)
    a, v = None, None
    if ado is not None:
        a = np.asarray(ado, dtype=np.float64).reshape(-1, 5)
        v = (np.ones(len(a), bool) if ado_valid is None
             else np.asarray(ado_valid, dtype=bool).reshape(-1))
        if v.shape[0] != a.shape[0]:
            raise ValueError(f"ado_valid must have {a.shape[0]} entries, got {v.shape[0]}")
        a, v = a[None], v[None]
    return _render([m], pose[None], a, v, cfg, draw_ego,
                   check_history(history, cfg, 1, a is not None))[0]


def rasterize_batch(
    maps: list[Map] | Map,
    ego_poses: np.ndarray,
    ado: np.ndarray | None = None,
    ado_valid: np.ndarray | None = None,
    cfg: RasterConfig | None = None,
    draw_ego: bool = True,
    history: History | None = None,
) -> np.ndarray:
    """Rasterise S frames: ``ego_poses (S, 3)``, ``ado (S, A, 5)``, ``ado_valid (S, A)``.

    ``maps`` is one map per frame, or a single map for all. Returns uint8
    ``(S, *cfg.shape)`` as stored (see :func:`rasterize`); frames are rendered together
    (vectorised over frames).
    ``history``: the frames' past (:class:`History` of ``S`` frames and
    ``cfg.history`` steps), required when ``cfg.history > 0`` and ados are drawn.
    """
    cfg = cfg or RasterConfig()
    poses = np.asarray(ego_poses, dtype=np.float64)
    if poses.ndim != 2 or poses.shape[1] != 3 or not np.all(np.isfinite(poses)):
        raise ValueError(f"ego_poses must be finite with shape (S, 3), got {poses.shape}")
    S = poses.shape[0]
    if isinstance(maps, Map):
        maps = [maps] * S
    if len(maps) != S:
        raise ValueError(f"maps must have {S} entries, got {len(maps)}")
    a, v = None, None
    if ado is not None:
        a = np.asarray(ado, dtype=np.float64)
        if a.ndim != 3 or a.shape[0] != S or a.shape[2] != 5:
            raise ValueError(f"ado must have shape ({S}, A, 5), got {a.shape}")
        v = (np.ones(a.shape[:2], bool) if ado_valid is None
             else np.asarray(ado_valid, dtype=bool))
        if v.shape != a.shape[:2]:
            raise ValueError(f"ado_valid must have shape {a.shape[:2]}, got {v.shape}")
    return _render(list(maps), poses, a, v, cfg, draw_ego,
                   check_history(history, cfg, S, a is not None))


def rasterize_goal(m: Map, goal_pose: np.ndarray, cfg: RasterConfig | None = None) -> np.ndarray:
    """Goal raster for RvS-G: the static map seen from the goal pose, ego box at the goal
    (in the channels encoding: the map's planes and the route on from the goal, the ego's,
    no vehicles)."""
    return rasterize(m, goal_pose, None, None, cfg)
