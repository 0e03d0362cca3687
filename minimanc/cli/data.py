"""Chapter 7 — ``minimanc data generate``, ``data show`` and ``data import-nuscenes``
(:mod:`minimanc.world`, :mod:`minimanc.world.nuscenes`).

``register(subparsers)`` adds the ``data`` command to the parser of :mod:`minimanc.cli`;
each subcommand sets ``func(args) -> int``.
"""

from __future__ import annotations

import argparse
import shutil
import sys
import time
from pathlib import Path
from typing import Any

from minimanc import world
from minimanc.checks import check_int
from minimanc.cli.common import check_option, check_out_dir, check_out_file, load_data
from minimanc.errors import UsageError
from minimanc.viz.world import gallery, plot_map, save_scene_gif, scene_frames
from minimanc.world import nuscenes

__all__ = ["DISK_MARGIN", "cmd_generate", "cmd_import_nuscenes", "cmd_show", "default_file",
           "register"]

DISK_MARGIN = 1.2
"""``data generate`` refuses to start unless the disk has this times the estimated size free."""


def default_file(out: str | Path, n_scenes: int, seed: int) -> Path:
    """File name used by ``data generate`` for ``n_scenes`` scenes from ``seed``."""
    return Path(out) / f"world_{n_scenes}x{seed}.npz"


def _raster(size: Any, option: str = "--size") -> Any:
    check_option(check_int, option, size, 8)
    return world.RasterConfig(size=size)


def cmd_generate(args: argparse.Namespace) -> int:
    """Generate scenes straight to a file, after checking the arguments and the free disk."""
    check_option(check_int, "--scenes", args.scenes, 1)
    check_option(check_int, "--seed", args.seed, 0)
    cfg = _raster(args.size)
    if args.workers is not None:
        check_option(check_int, "--workers", args.workers, 1)
    out = check_out_dir(args.out)
    path = default_file(out, args.scenes, args.seed)
    if path.is_dir():
        raise UsageError(f"--out {out}: {path.name} is a directory")
    est = world.estimate(args.scenes, seed=args.seed, raster=cfg, workers=args.workers)
    free = shutil.disk_usage(out).free
    print(f"estimate for {args.scenes} scenes: {est}", file=sys.stderr)
    if est.disk_bytes * DISK_MARGIN > free:
        raise UsageError(f"not enough free disk space in {out}: {args.scenes} scenes need about "
                         f"{est.disk_bytes / 1e9:.2f} GB (+{DISK_MARGIN - 1:.0%} margin), "
                         f"{free / 1e9:.2f} GB are free; use fewer --scenes or another --out")
    t0 = time.perf_counter()
    try:
        path = world.generate_file(path, args.scenes, seed=args.seed, raster=cfg,
                                   progress=not args.quiet, workers=args.workers)
    except OSError as e:  # e.g. the disk filled up: nothing is left behind
        raise UsageError(f"cannot write {path}: {e.strerror or e}") from e
    dt = time.perf_counter() - t0
    tags = world.read_meta(path)["tags"]
    share = {k: sum(bool(t[k]) for t in tags) / len(tags)
             for k in ("has_junction", "has_roundabout", "has_cut_in")}
    print(f"generated {len(tags)} scenes (seed {args.seed}) in {dt:.1f} s -> {path} "
          f"({path.stat().st_size / 1e6:.1f} MB)")
    print("  " + ", ".join(f"{k}: {v:.0%}" for k, v in share.items()))
    print(f"  content hash {world.file_content_hash(path)[:16]}")
    return 0


def cmd_import_nuscenes(args: argparse.Namespace) -> int:
    """Import a nuScenes DATAROOT's scenes into a dataset file, after estimating the disk."""
    if args.version not in nuscenes.VERSIONS:
        raise UsageError(f"--version must be one of {', '.join(nuscenes.VERSIONS)}, got "
                         f"{args.version!r}")
    cfg = _raster(args.size)
    path = check_out_file(args.out or Path("data") / f"nuscenes_{args.version}.npz")
    try:
        tables, expansions = nuscenes.Tables(args.dataroot, args.version), {}
        est = nuscenes.estimate_import(args.dataroot, args.version, args.scenes, raster=cfg,
                                       tables=tables, expansions=expansions)
        free = shutil.disk_usage(path.parent).free
        print(f"estimate for {est.n_scenes} scenes: {est}", file=sys.stderr)
        if est.disk_bytes * DISK_MARGIN > free:
            raise UsageError(f"not enough free disk space in {path.parent}: {est.n_scenes} "
                             f"scenes need about {est.disk_bytes / 1e9:.2f} GB "
                             f"(+{DISK_MARGIN - 1:.0%} margin), {free / 1e9:.2f} GB are free; "
                             "import fewer --scenes or choose another --out")
        report = nuscenes.import_nuscenes(args.dataroot, args.version, path, args.scenes,
                                          raster=cfg, progress=not args.quiet, tables=tables,
                                          expansions=expansions)
    except nuscenes.NuScenesError as e:
        raise UsageError(str(e)) from e
    except OSError as e:  # e.g. the disk filled up: nothing is left behind
        raise UsageError(f"cannot write {path}: {e.strerror or e}") from e
    print(report)
    print(f"  {path.stat().st_size / 1e6:.1f} MB, content hash "
          f"{world.file_content_hash(path)[:16]}")
    return 0


def cmd_show(args: argparse.Namespace) -> int:
    """Write a raster gallery, a scene animation and a map plot of one scene."""
    import matplotlib  # matplotlib only when a figure is drawn

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # matplotlib only when a figure is drawn

    if args.scene is not None:
        check_option(check_int, "--scene", args.scene, 0)
    if args.data:
        ds = load_data(args.data)
    else:
        check_option(check_int, "--scenes", args.scenes, 1)
        check_option(check_int, "--seed", args.seed, 0)
    out = check_out_dir(args.out)
    if not args.data:
        ds = world.generate(args.scenes, seed=args.seed, progress=False)
    scene = args.scene if args.scene is not None else next(
        (i for i, t in enumerate(ds.tags) if t["has_roundabout"] or t["has_junction"]), 0)
    if not 0 <= scene < len(ds):
        raise UsageError(f"--scene must be in [0, {len(ds) - 1}] (the dataset has {len(ds)} "
                         f"scenes), got {scene}")
    fig = gallery(ds, range(min(len(ds), 12)))
    fig.savefig(out / "gallery.png", dpi=120)
    plt.close(fig)
    save_scene_gif(scene_frames(ds, scene), out / "scene.gif")
    fig, ax = plt.subplots(figsize=(6, 6))
    plot_map(ds.maps[scene], ax, ego=ds.ego[scene], ado=ds.ado[scene],
                 ado_valid=ds.ado_valid[scene])
    fig.savefig(out / "scene_map.png", dpi=120)
    plt.close(fig)
    print(f"wrote {out / 'gallery.png'}, {out / 'scene.gif'} (scene {scene}) and "
          f"{out / 'scene_map.png'}")
    return 0


def register(subparsers: Any) -> None:
    """Add ``data generate``, ``data show`` and ``data import-nuscenes`` to an argparse
    sub-parser collection."""
    p = subparsers.add_parser("data", help="generate and inspect the BEV driving dataset")
    sub = p.add_subparsers(dest="data_command", required=True)
    g = sub.add_parser("generate", help="generate scenes and save them (.npz)",
                       description="Generate scenes straight to disk, one shard at a time "
                                   "(memory does not grow with --scenes). The estimated disk "
                                   "size and time are printed first; the command refuses to "
                                   "start if the disk lacks the space.")
    g.add_argument("--scenes", type=int, default=850, help="number of scenes (default 850)")
    g.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    g.add_argument("--out", default="data", help="output directory (default ./data)")
    g.add_argument("--size", type=int, default=64, help="raster size in pixels (default 64)")
    g.add_argument("--workers", type=int, default=None, help="processes (default: auto)")
    g.add_argument("--quiet", action="store_true", help="no progress bar")
    g.set_defaults(func=cmd_generate)
    s = sub.add_parser("show", help="write a raster gallery (PNG) and a scene animation (GIF)")
    s.add_argument("--out", default="data/show", help="output directory (default ./data/show)")
    s.add_argument("--data", default=None, help="a saved dataset file (default: generate)")
    s.add_argument("--scenes", type=int, default=12, help="scenes to generate (default 12)")
    s.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    s.add_argument("--scene", type=int, default=None, help="scene to animate")
    s.set_defaults(func=cmd_show)
    n = sub.add_parser("import-nuscenes", help="import real nuScenes scenes (.npz)",
                       description="Import the scenes of a nuScenes DATAROOT (the version's "
                                   "JSON tables and maps/expansion/*.json) into the world's "
                                   "dataset format, one shard at a time. Scenes of fewer "
                                   "than 40 keyframes or with a dropped keyframe are skipped "
                                   "and listed. The estimated disk size and time are printed "
                                   "first; the command refuses to start if the disk lacks "
                                   "the space.")
    n.add_argument("dataroot", help="the nuScenes DATAROOT (holding <version>/ and maps/)")
    n.add_argument("--version", required=True, help="dataset version: v1.0-mini or "
                   "v1.0-trainval (minimanc.world.nuscenes.VERSIONS)")
    n.add_argument("--out", default=None,
                   help="output file (default ./data/nuscenes_<version>.npz)")
    n.add_argument("--scenes", nargs="+", default=None, metavar="NAME",
                   help="scene names (default: every scene of the version's splits)")
    n.add_argument("--size", type=int, default=64, help="raster size in pixels (default 64)")
    n.add_argument("--quiet", action="store_true", help="no progress bar")
    n.set_defaults(func=cmd_import_nuscenes)

