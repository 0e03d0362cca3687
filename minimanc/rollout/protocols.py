"""Chapter 9 — the two protocols for the ados, chosen by ``agents`` (:data:`AGENTS`):
:func:`simulate` (a policy on many scenes) and :func:`human` (Table I's "Human" row).

Every rollout of the package is called the same way: the dataset ``ds`` (after the policy,
for :func:`simulate`), then ``scenes`` (default: all), then keyword options, ``agents``
among them, and it returns a :class:`~minimanc.rollout.Rollout`:
``simulate(policy, ds, scenes, agents="reactive")``, ``human(ds, agents="reactive")``,
``fixed_gains(ds, agents="reactive")``, ``closed_loop(fit, ds, agents="reactive")``.

``"replay"`` is the paper's: the ados replay the log (:class:`~minimanc.rollout.LogReplay`).
``"reactive"`` drives them by the world's own rules, reacting to the policy's ego
(:class:`~minimanc.rollout.reactive.ReactiveSim`). Both run the same batching loop
(:func:`minimanc.rollout.log.run_batches`); this module only picks the simulator, so that
neither protocol's module imports the other's.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from minimanc.rollout.driver import Policy
from minimanc.rollout.log import (
    AGENTS,
    LogReplay,
    Rollout,
    check_agents,
    check_dataset,
    run_batches,
    scene_index,
)
from minimanc.rollout.reactive import LoggedControls, ReactiveSim

__all__ = ["AGENTS", "human", "simulate"]


def simulate(
    policy: Policy,
    ds: Any,
    scenes: Any = None,
    *,
    batch_size: int | None = None,
    steps: int | None = None,
    progress: bool = True,
    desc: str | None = None,
    agents: str = "replay",
) -> Rollout:
    """Run ``policy`` in closed loop on the scenes ``scenes`` of ``ds`` (default: all).

    Scenes are processed ``batch_size`` at a time (default
    :data:`~minimanc.rollout.BATCH_SIZE` = 8: the world keeps the class grids of 8 maps
    cached, and a larger batch would rebuild every grid at every step); a row's result does
    not depend on the batch it is in.  ``steps`` limits the number of decisions (default
    ``T − 1``, the whole log).  Each batch is :func:`~minimanc.rollout.drive` in a
    :class:`~minimanc.rollout.LogReplay`; see the package docstring for what one step does.
    ``agents="reactive"`` drives the ados by the world's rules instead, reacting to the
    policy's ego (:class:`~minimanc.rollout.reactive.ReactiveSim`; the rollout then holds
    the simulated ados).

    Parameters
    ----------
    policy : Policy
        The driver (:class:`~minimanc.rollout.Policy`).
    ds : dataset
        A :mod:`minimanc.world` dataset.
    scenes : array_like of int, optional
        Its scenes to drive (default: all).
    batch_size, steps : int, optional
        Scenes driven together, decisions per scene.
    progress : bool
        A tqdm bar.
    desc : str, optional
        The bar's label.
    agents : str
        The ados' protocol (:data:`AGENTS`).

    Returns
    -------
    Rollout
        Under ``"reactive"`` with the ados as they were simulated (``ado``, ``ado_valid``).
    """
    make_sim = ReactiveSim if check_agents(agents) == "reactive" else LogReplay
    return run_batches(policy, ds, make_sim, agents, scenes=scenes, batch_size=batch_size,
                       steps=steps, progress=progress, desc=desc)


def human(ds: Any, scenes: Any = None, *, agents: str = "replay") -> Rollout:
    """The logged human ego as a :class:`~minimanc.rollout.Rollout` (Table I's "Human" row).

    Its controls are the logged ones from ``t`` to ``t + 1``; replaying them
    with the unicycle reproduces ``ds.ego`` (the world's logging rule).  With
    ``agents="reactive"`` these controls drive the ego among reactive ados
    (:class:`~minimanc.rollout.reactive.LoggedControls` in :func:`simulate`): the same poses,
    and the ados as the reactive simulation moved them (equal to the log to float32
    rounding).

    Parameters
    ----------
    ds : dataset
        A :mod:`minimanc.world` dataset.
    scenes : array_like of int, optional
        Its scenes (default: all).
    agents : str
        The ados' protocol (:data:`AGENTS`).

    Returns
    -------
    Rollout
        Named ``"human"``, setting ``"log"``.
    """
    if check_agents(agents) == "reactive":
        traj = simulate(LoggedControls(ds), ds, scenes=scenes, progress=False,
                        desc="reactive closed loop human", agents="reactive")
        traj.name = "human"
        return traj
    S, T = check_dataset(ds)
    idx = scene_index(scenes, S)
    ego = np.asarray(ds.ego, dtype=np.float64)[idx]
    controls = np.asarray(ds.controls, dtype=np.float64)[idx, : T - 1]
    return Rollout("human", "log", ego, controls, {}, idx)
