"""Chapter 10 — rendering: highway-env's frames headless, to PNG and GIF.

Headless rendering needs ``SDL_VIDEODRIVER=offscreen`` (``dummy`` gives black
frames), which :mod:`minimanc.highway` sets before highway-env is imported.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from minimanc.checks import check_int


def render_frame(env) -> np.ndarray:
    """highway-env's own top-down frame ``(H, W, 3)`` uint8, rendered headless.

    Needs ``render_mode="rgb_array"`` (``make_env(..., render=True)``). After
    rendering, ``enable_auto_render`` is switched off: otherwise every later
    ``step`` renders each sub-step too (about 4x slower).
    """
    u = env.unwrapped
    if u.render_mode != "rgb_array":
        raise ValueError(
            f"env.render_mode must be 'rgb_array' to render frames, got {u.render_mode!r}; "
            "use make_env(..., render=True)"
        )
    frame = np.asarray(u.render(), dtype=np.uint8)
    u.enable_auto_render = False
    return frame


def save_png(frame: np.ndarray, path: str | Path, scale: int = 1) -> Path:
    """Save an ``(H, W, 3)`` uint8 frame as PNG, optionally upscaled ``scale`` times (nearest)."""
    from PIL import Image  # Pillow only when an image is written

    f = _check_frame(frame)
    img = Image.fromarray(f)
    scale = check_int("scale", scale, 1)
    if scale > 1:
        img = img.resize((f.shape[1] * scale, f.shape[0] * scale), Image.NEAREST)
    path = Path(path)
    img.save(path, format="PNG")
    return path


def save_gif(frames: Sequence[np.ndarray], path: str | Path, fps: float = 2.0,
             scale: int = 1) -> Path:
    """Save frames ``(H, W, 3)`` uint8 as a looping GIF at ``fps`` frames per second."""
    from PIL import Image  # Pillow only when an image is written

    if len(frames) == 0:
        raise ValueError("frames must hold at least one frame, got 0")
    if not (np.isfinite(fps) and fps > 0):
        raise ValueError(f"fps must be positive, got {fps!r}")
    scale = check_int("scale", scale, 1)
    imgs = []
    for fr in frames:
        f = _check_frame(fr)
        img = Image.fromarray(f)
        if scale > 1:
            img = img.resize((f.shape[1] * scale, f.shape[0] * scale), Image.NEAREST)
        imgs.append(img)
    path = Path(path)
    imgs[0].save(path, format="GIF", save_all=True, append_images=imgs[1:],
                 duration=int(round(1000.0 / fps)), loop=0)
    return path


def _check_frame(frame: np.ndarray) -> np.ndarray:
    f = np.asarray(frame)
    if f.ndim != 3 or f.shape[2] != 3 or f.dtype != np.uint8:
        raise ValueError(f"frame must be an (H, W, 3) uint8 array, got {f.shape} {f.dtype}")
    return f
