"""Chapter 7 — faded history: every vehicle's last steps drawn into the BEV as boxes of
decreasing brightness, so that speed and closing speed are visible in one image.

The nuScenes devkit's prediction raster (``AgentBoxesWithFadedHistory``) draws each agent's
boxes of the last seconds, the oldest faintest. The authors' released environment draws
each vehicle once, at its current pose; so does :class:`minimanc.world.RasterConfig` with
``history = 0`` (the default). With ``history = H`` the raster draws, under the current
boxes, the boxes of the ``H`` previous steps (``DT`` apart), the ego's own included, in
the colour of the vehicle scaled by :func:`fade` (``1 − j/(H+1)`` for the box ``j`` steps
ago).

:class:`History` holds those past boxes for ``S`` frames; :func:`history_of` builds it for
every step of a recorded track (the log when the dataset is written, the closed loop's
own trajectory when it is driven), so the two draw the same image from the same states.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from minimanc.checks import check_int

__all__ = ["MAX_HISTORY", "History", "fade", "history_of", "latest_history"]

MAX_HISTORY: int = 8
"""The most past steps a raster draws (4 s at 2 Hz)."""


@dataclass
class History:
    """The past of ``S`` frames, ``H`` steps: ``ego (S, H, 3)`` poses and ``ado (S, H, A, 5)``
    boxes ``j + 1`` steps before each frame at index ``j``, with ``ego_valid (S, H)`` and
    ``ado_valid (S, H, A)`` saying which exist (none before the first step)."""

    ego: np.ndarray
    ego_valid: np.ndarray
    ado: np.ndarray
    ado_valid: np.ndarray

    def __post_init__(self) -> None:
        self.ego = np.asarray(self.ego, dtype=np.float64)
        self.ego_valid = np.asarray(self.ego_valid, dtype=bool)
        self.ado = np.asarray(self.ado, dtype=np.float64)
        self.ado_valid = np.asarray(self.ado_valid, dtype=bool)
        S, H = self.ego_valid.shape if self.ego_valid.ndim == 2 else (-1, -1)
        if (self.ego.shape != (S, H, 3) or self.ado.ndim != 4 or self.ado.shape[:2] != (S, H)
                or self.ado.shape[3] != 5 or self.ado_valid.shape != self.ado.shape[:3]):
            raise ValueError(
                f"History needs ego (S, H, 3), ego_valid (S, H), ado (S, H, A, 5), ado_valid "
                f"(S, H, A); got {self.ego.shape}, {self.ego_valid.shape}, {self.ado.shape}, "
                f"{self.ado_valid.shape}")
        if not (np.all(np.isfinite(self.ego[self.ego_valid]))
                and np.all(np.isfinite(self.ado[self.ado_valid]))):
            raise ValueError("History: the valid past poses and boxes must be finite")

    @property
    def steps(self) -> int:
        return int(self.ego_valid.shape[1])


def fade(steps: int) -> np.ndarray:
    """Brightness ``(H,)`` of the boxes ``1 … H`` steps ago: ``1 − j/(H+1)``."""
    steps = check_int("steps", steps, 1, MAX_HISTORY)
    return 1.0 - np.arange(1, steps + 1) / (steps + 1.0)


def history_of(ego: np.ndarray, ado: np.ndarray, ado_valid: np.ndarray, steps: int,
               frames: np.ndarray | None = None) -> History:
    """The :class:`History` of ``steps`` past steps for the frames ``frames`` (default: every
    step) of one track: ``ego (T, 3)``, ``ado (T, A, 5)``, ``ado_valid (T, A)``; frame ``t``
    sees steps ``t − 1, …, t − steps`` (invalid before 0)."""
    steps = check_int("steps", steps, 1, MAX_HISTORY)
    e = np.asarray(ego, dtype=np.float64)
    a = np.asarray(ado, dtype=np.float64)
    v = np.asarray(ado_valid, dtype=bool)
    if e.ndim != 2 or e.shape[1] != 3 or a.shape[:1] != e.shape[:1] or a.ndim != 3 \
            or v.shape != a.shape[:2]:
        raise ValueError(f"history_of needs ego (T, 3), ado (T, A, 5), ado_valid (T, A); got "
                         f"{e.shape}, {a.shape}, {v.shape}")
    T = len(e)
    t = np.arange(T) if frames is None else np.asarray(frames, dtype=np.int64)
    if t.ndim != 1 or np.any((t < 0) | (t >= T)):
        raise ValueError(f"frames must be steps in [0, {T}); got {frames!r}")
    past = t[:, None] - np.arange(1, steps + 1)[None, :]  # (S, H)
    ok = past >= 0
    idx = np.maximum(past, 0)
    return History(np.where(ok[..., None], e[idx], 0.0), ok,
                   np.where(ok[..., None, None], a[idx], 0.0), v[idx] & ok[..., None])


def latest_history(ego: np.ndarray, ado: np.ndarray, ado_valid: np.ndarray,
                   steps: int) -> History:
    """The :class:`History` of the last step of ``B`` tracks driven so far: ``ego (B, t+1, 3)``,
    ``ado (B, t+1, A, 5)``, ``ado_valid (B, t+1, A)`` (a closed loop's own record)."""
    e = np.asarray(ego, dtype=np.float64)
    if e.ndim != 3:
        raise ValueError(f"ego must have shape (B, t+1, 3); got {e.shape}")
    parts = [history_of(e[b], ado[b], ado_valid[b], steps, frames=[e.shape[1] - 1])
             for b in range(e.shape[0])]
    return History(np.concatenate([p.ego for p in parts]),
                   np.concatenate([p.ego_valid for p in parts]),
                   np.concatenate([p.ado for p in parts]),
                   np.concatenate([p.ado_valid for p in parts]))
