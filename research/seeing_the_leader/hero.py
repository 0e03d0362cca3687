"""The README's figure: the learner's MANC driving a validation scene in which the human brakes
for the car ahead (the paper's Fig. 4 for one scene,
:func:`minimanc.viz.explain.plot_explain_trace`).

The driver is ``end_to_end.py``'s MANC in the learner's form (``manc_qp`` with the form
``dagger_flat_warm2_p64_goal10``: the flattened read-out, 64 predicates, gains over q ⊕ p,
the DMP's goal a fixed 10 m ahead, DAgger with two epochs per continuing round), loaded as
the library's ``"manc"`` with ``ModelConfig.gains_input = "q_p"`` (the same parameters and
the same step; checked on the scene's first observations before drawing). The scene is
chosen by rule, not by eye: among the validation scenes (600–799) that MANC drives among
reactive ados without a collision, the one with the most steps in which the human brakes
because of its leader (:func:`leader_data.leader_brakes`); the BEV panels show its first,
middle and last steps.

Run: ``SEEING_DATA=/path python research/seeing_the_leader/hero.py --work runs/end_to_end
--seed 1`` (writes ``docs/figures/driver.png``).
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

import end_to_end as E
import leader_data as L
import numpy as np

from minimanc import inputs, models, rollout, train
from minimanc.engine import get_engine
from minimanc.metrics.safety import collisions
from minimanc.viz.explain import plot_explain_trace
from minimanc.viz.style import save_figure

FORM = "dagger_flat_warm2_p64_goal10"
OUT = Path(__file__).resolve().parents[2] / "docs" / "figures" / "driver.png"


def as_library_manc(fit: train.FitResult) -> train.FitResult:
    """``manc_qp``'s fit as the library's MANC with gains over q ⊕ p."""
    return replace(fit, name="manc", cfg=replace(fit.cfg, gains_input="q_p"))


def check_same_step(a: train.FitResult, b: train.FitResult, obs: dict) -> None:
    """Both fits give the same controls on ``obs`` (one step from the initial state)."""
    eng = get_engine("numpy")
    outs = [np.asarray(models.step(f.name, f.params, obs,
                                   models.initial_state(f.name, len(obs["motion"]), f.cfg),
                                   f.cfg, eng)[0]) for f in (a, b)]
    if not np.allclose(outs[0], outs[1], rtol=1e-6, atol=1e-6):
        raise SystemExit("the library's MANC with gains over q ⊕ p differs from manc_qp")


def pick_scene(traj: rollout.Rollout, brakes: np.ndarray) -> int:
    """The scene without a collision with the most steps of braking for the leader."""
    collided = collisions(traj.ego, traj.ado, traj.ado_valid) > 0
    return int(np.argmax(np.where(collided, -1, brakes.sum(axis=1))))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--work", type=Path, required=True)
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    ck = E.checkpoint_of("manc_qp", FORM, args.seed, args.work)
    if ck is None:
        raise SystemExit(f"no checkpoint of manc_qp {FORM} seed {args.seed} under {args.work}")
    qp = train.load_fit(ck)
    fit = as_library_manc(qp)
    ds = E.draw(FORM, args.work)
    val = ds.subset(list(E.VALIDATE))
    n = min(8, len(val))
    check_same_step(qp, fit, inputs.from_dataset(val, np.arange(n), np.zeros(n, int)))
    traj = rollout.closed_loop(fit, val, agents="reactive", progress=False)
    human = rollout.human(val, agents="reactive")
    tg = L.targets(progress=False)
    brakes = L.leader_brakes(tg)[E.VALIDATE.start:E.VALIDATE.stop]
    s = pick_scene(traj, brakes)
    fig = plot_explain_trace(traj, human, val, s)
    print(f"scene {E.VALIDATE.start + s}: {int(brakes[s].sum())} steps of braking for the "
          f"leader; wrote {save_figure(fig, OUT)}")


if __name__ == "__main__":
    main()
