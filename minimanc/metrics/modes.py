"""Chapter 9 — are vAGN's q-states driving modes? A measurement, not an assertion.

The paper says vAGN (eqs. 8–9) "learns semantically meaningful driving modes". The
world knows, at every step of a logged scene, what the human driver was doing
(:func:`human_modes`, from the same simulation that generated the log):

========== ================================================================
mode       the human at this step
========== ================================================================
yield      brakes (or waits) for a junction conflict it must yield to
follow     brakes for a leader in its corridor
roundabout drives on a roundabout's ring or its entry/exit connectors
junction   drives through an intersection's connector lanes
free       none of the above
========== ================================================================

(earlier rows win). If q's most likely state ``argmax q_t`` tracks these modes, it
carries information about them: :func:`mode_information` measures the **mutual
information** ``I(argmax q; mode)`` in bits (plug-in estimate from the contingency
table), against a **shuffled-scene baseline**: the q-sequence of each scene paired with
the modes of another scene (a random permutation of the scenes), which keeps the time
structure of both series (a q that cycles like a clock, or a mode that lasts, is not
information about the scene). It also reports how much q moves from step to step (the
mean total-variation distance ``½ Σ |q_t − q_{t−1}|``) and how often its most likely
state switches.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from minimanc.checks import check_int
from minimanc.rollout import reactive

__all__ = [
    "MODES",
    "entropy",
    "human_modes",
    "mode_information",
    "mutual_information",
    "scene_modes",
]

MODES: tuple[str, ...] = ("free", "follow", "yield", "junction", "roundabout")
"""The human's modes, by their integer label (see the module docstring)."""


def _lane_mode(run: Any) -> int:
    """``junction``/``roundabout``/``free`` from the lane under the ego of a scene run."""
    path, s = run.path, float(run.ego.s)
    j = int(np.clip(np.searchsorted(path.starts, s, side="right") - 1, 0, len(path.lanes) - 1))
    lane = run.m.lanes[path.lanes[j]]
    if lane.kind == "ring" or (lane.junction >= 0 and run.m.kind == "roundabout"):
        return MODES.index("roundabout")
    if lane.junction >= 0:
        return MODES.index("junction")
    return MODES.index("free")


def scene_modes(ds: Any, i: int) -> np.ndarray:
    """The human's mode at each step of scene ``i`` of a :mod:`minimanc.world` dataset.

    Re-runs the scene from its seed with the human driving
    (:func:`minimanc.rollout.reactive.start_scene`) and checks that the run reproduces the
    logged ego poses.

    Parameters
    ----------
    ds : minimanc.world.Dataset
        A dataset made by :func:`minimanc.world.generate` (its meta names the seeds).
    i : int
        The scene (row of ``ds``).

    Returns
    -------
    numpy.ndarray of int, shape (T,)
        Indices into :data:`MODES`.

    Raises
    ------
    ValueError
        When the dataset was not made by :func:`minimanc.world.generate` or the run does
        not reproduce its log.
    """
    key = reactive.scene_key(ds, i)
    run = reactive.start_scene(key, ds.maps[i], ds.meta["recipes"][i])
    modes = np.zeros(key.steps, dtype=np.int64)
    ego = np.zeros((key.steps, 3))
    for t in range(key.steps):
        ego[t] = run.pose
        lane = _lane_mode(run)
        run.human_step()
        binding = run.kinds[-1]
        modes[t] = MODES.index("yield") if binding == "yield" else (
            MODES.index("follow") if binding == "leader" else lane)
    if not np.array_equal(ego.astype(np.float32), np.asarray(ds.ego[i])):
        raise ValueError(f"scene {i} of ds does not regenerate its logged ego poses: the "
                         "dataset was made by another version of minimanc.world")
    return modes


def human_modes(ds: Any, scenes: Sequence[int] | None = None) -> np.ndarray:
    """:func:`scene_modes` of several scenes (all by default): ``(S, T)`` int labels."""
    idx = range(len(ds.ego)) if scenes is None else [int(s) for s in scenes]
    return np.stack([scene_modes(ds, i) for i in idx])


def _labels(name: str, x: Any) -> np.ndarray:
    a = np.asarray(x)
    if a.size == 0 or not np.issubdtype(a.dtype, np.integer) or a.min() < 0:
        raise ValueError(f"{name} must be a non-empty array of non-negative integer labels, "
                         f"got dtype {a.dtype} and shape {a.shape}")
    return a.astype(np.int64)


def entropy(labels: Any) -> float:
    """Entropy (bits) of the empirical distribution of integer ``labels``.

    Parameters
    ----------
    labels : array of int
        Non-negative labels, any shape.

    Returns
    -------
    float
        ``−Σ p log₂ p`` over the labels' frequencies ``p``.
    """
    a = _labels("labels", labels).ravel()
    p = np.bincount(a) / a.size
    p = p[p > 0]
    return float(-(p * np.log2(p)).sum())


def mutual_information(a: Any, b: Any) -> float:
    """Plug-in mutual information ``I(a; b)`` (bits) of two paired integer label arrays.

    Parameters
    ----------
    a, b : array of int
        Non-negative labels of the same shape (paired element by element).

    Returns
    -------
    float
        ``H(a) + H(b) − H(a, b)`` of the empirical joint distribution, ≥ 0.

    Raises
    ------
    ValueError
        On arrays of different shapes or non-integer labels.
    """
    a, b = _labels("a", a), _labels("b", b)
    if a.shape != b.shape:
        raise ValueError(f"a and b must have the same shape, got {a.shape} and {b.shape}")
    a, b = a.ravel(), b.ravel()
    joint = a * (int(b.max()) + 1) + b
    return max(0.0, entropy(a) + entropy(b) - entropy(joint))


def mode_information(q: Any, modes: Any, n_shuffles: int = 200, seed: int = 0) -> dict:
    """How much vAGN's most likely state says about the human's mode.

    Parameters
    ----------
    q : array, shape (S, T, N)
        The q-distributions over ``S`` scenes of ``T`` steps (e.g. from
        :func:`minimanc.rollout.replay`).
    modes : array of int, shape (S, T)
        The human's modes (:func:`human_modes`).
    n_shuffles : int, optional (default: 200)
        Scene permutations of the baseline.
    seed : int, optional (default: 0)
        Seed of the permutations.

    Returns
    -------
    dict
        ``mi_bits`` = I(argmax q; mode); ``shuffled_mi_bits`` (mean) and
        ``shuffled_mi_p95`` of the shuffled-scene baseline; ``excess_bits`` = ``mi_bits −
        shuffled_mi_bits``; ``p_value`` (share of shuffles with an MI at least
        ``mi_bits``, with the observed one counted); ``mode_entropy_bits`` = H(mode), the
        most any q could carry; ``states_used`` (distinct argmax states); ``q_change`` =
        mean ½ Σ |q_t − q_{t−1}| and ``switch_rate`` = share of steps whose argmax
        differs from the previous step's.

    Raises
    ------
    ValueError
        On shapes that do not match, non-finite q, or fewer than 2 scenes.
    """
    q = np.asarray(q, dtype=np.float64)
    modes = _labels("modes", modes)
    if q.ndim != 3 or modes.shape != q.shape[:2]:
        raise ValueError(f"q must have shape (S, T, N) and modes (S, T), got {q.shape} and "
                         f"{modes.shape}")
    if not np.all(np.isfinite(q)):
        raise ValueError("q must be finite")
    S = q.shape[0]
    if S < 2:
        raise ValueError(f"the shuffled-scene baseline needs at least 2 scenes, got {S}")
    n_shuffles = check_int("n_shuffles", n_shuffles, 1)
    state = q.argmax(axis=-1)
    mi = mutual_information(state, modes)
    rng = np.random.default_rng(check_int("seed", seed, 0))
    null = np.array([mutual_information(state, modes[rng.permutation(S)])
                     for _ in range(n_shuffles)])
    return {
        "mi_bits": mi,
        "shuffled_mi_bits": float(null.mean()),
        "shuffled_mi_p95": float(np.quantile(null, 0.95)),
        "excess_bits": mi - float(null.mean()),
        "p_value": float((1 + np.sum(null >= mi - 1e-12)) / (1 + n_shuffles)),
        "mode_entropy_bits": entropy(modes),
        "states_used": int(np.unique(state).size),
        "q_change": float(0.5 * np.abs(np.diff(q, axis=1)).sum(axis=-1).mean())
        if q.shape[1] > 1 else 0.0,
        "switch_rate": float(np.mean(state[:, 1:] != state[:, :-1])) if q.shape[1] > 1 else 0.0,
    }
