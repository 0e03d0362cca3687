"""Chapter 7 — command line: ``minimanc data generate`` and ``minimanc data show``.

``register(subparsers)`` adds the ``data`` command to the main parser of
:mod:`minimanc.cli`; each subcommand sets ``func(args) -> int``.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path


def default_file(out: str | Path, n_scenes: int, seed: int) -> Path:
    """File name used by ``data generate`` for ``n_scenes`` scenes from ``seed``."""
    return Path(out) / f"world_{n_scenes}x{seed}.npz"


def cmd_generate(args: argparse.Namespace) -> int:
    from minimanc import world

    cfg = world.RasterConfig(size=args.size)
    t0 = time.perf_counter()
    ds = world.generate(args.scenes, seed=args.seed, raster=cfg, progress=not args.quiet,
                        workers=args.workers)
    dt = time.perf_counter() - t0
    path = world.save(ds, default_file(args.out, args.scenes, args.seed))
    tags = ds.tags
    share = {k: sum(bool(t[k]) for t in tags) / len(tags)
             for k in ("has_junction", "has_roundabout", "has_cut_in")}
    print(f"generated {len(ds)} scenes (seed {args.seed}) in {dt:.1f} s -> {path}")
    print("  " + ", ".join(f"{k}: {v:.0%}" for k, v in share.items()))
    print(f"  content hash {ds.content_hash()[:16]}")
    return 0


def cmd_show(args: argparse.Namespace) -> int:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from minimanc import world
    from minimanc.world import viz

    if args.data:
        ds = world.load(args.data)
    else:
        ds = world.generate(args.scenes, seed=args.seed, progress=False)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    fig = viz.gallery(ds, range(min(len(ds), 12)))
    fig.savefig(out / "gallery.png", dpi=120)
    plt.close(fig)
    scene = args.scene if args.scene is not None else next(
        (i for i, t in enumerate(ds.tags) if t["has_roundabout"] or t["has_junction"]), 0)
    if not 0 <= scene < len(ds):
        raise SystemExit(f"--scene must be in [0, {len(ds) - 1}], got {scene}")
    viz.save_gif(viz.scene_frames(ds, scene), out / "scene.gif")
    fig, ax = plt.subplots(figsize=(6, 6))
    viz.plot_map(ds.maps[scene], ax, ego=ds.ego[scene], ado=ds.ado[scene],
                 ado_valid=ds.ado_valid[scene])
    fig.savefig(out / "scene_map.png", dpi=120)
    plt.close(fig)
    print(f"wrote {out / 'gallery.png'}, {out / 'scene.gif'} (scene {scene}) and "
          f"{out / 'scene_map.png'}")
    return 0


def register(subparsers) -> None:
    """Add ``data generate`` and ``data show`` to an argparse sub-parser collection."""
    p = subparsers.add_parser("data", help="generate and inspect the BEV driving dataset")
    sub = p.add_subparsers(dest="data_command", required=True)
    g = sub.add_parser("generate", help="generate scenes and save them (.npz)")
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


def main(argv: list[str] | None = None) -> int:
    """Stand-alone entry point: ``python -m minimanc.world.cli data generate ...``."""
    parser = argparse.ArgumentParser(prog="minimanc")
    register(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(argv)
    return int(args.func(args))


if __name__ == "__main__":
    raise SystemExit(main())
