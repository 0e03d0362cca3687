"""Table I at the paper's data size in the learner's form, within one session of two cores.

``minimanc reproduce --preset paper`` trains 99 models (72 of them by DAgger) and drives
120 closed loops: many hours on two cores (``benchmarks/bench_study.py``). This script runs
the part that answers issue 41's closed-loop targets first: Table I alone, at the paper
preset's sizes (650 / 40 / 200 scenes, six epochs, DAgger for 10 rounds continuing two
epochs each, the learner's raster and models), but for one training seed, one learning
rate for every model (the quick preset's 1e-3, no sweep), MANC with 6 q-states, the paper
setting (``--setting parity``: the lane target and the own speed as numbers too;
``--models`` chooses which of Table I's models), and no q-state, data-fraction, ablation or
saliency study. The bound rows (the human, the expert, the style floor, the privileged
learner, the DMP at fixed gains) are the study's own. Everything is cached under ``--out``
(resumable: rerun the same command).

Run: ``python research/seeing_the_leader/paper_size.py --out /path/paper_size --workers 2``
(writes ``--out``'s ``table1.md`` and ``results.json``; ``--copy`` also copies them to
``results/paper_size_<setting>_<seeds>seed.md`` and ``.json`` here).
"""

from __future__ import annotations

import argparse
import shutil
import sys
from dataclasses import replace
from pathlib import Path

from minimanc import studies

HERE = Path(__file__).resolve().parent


def config(seeds: int, setting: str, table_models: tuple[str, ...]) -> studies.StudyConfig:
    """The paper preset cut down to Table I: ``seeds`` seeds, one learning rate, one
    ``setting``, the ``table_models``."""
    return replace(studies.PRESETS["paper"], preset="paper-table1", n_seeds=seeds,
                   lrs=(1e-3,), q_states=(6,), fractions=(1.0,), settings=(setting,),
                   table_models=table_models, ablation_models=(), sample_models=(),
                   explain_scenes=0)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", required=True)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--seeds", type=int, default=1)
    ap.add_argument("--setting", default="paper", choices=("paper", "parity"))
    ap.add_argument("--models", default=",".join(studies.TABLE_MODELS))
    ap.add_argument("--copy", action="store_true")
    args = ap.parse_args(argv)
    out = Path(args.out)
    table_models = tuple(args.models.split(","))
    studies.reproduce(config(args.seeds, args.setting, table_models), out,
                      workers=args.workers, progress=False, figures=False,
                      log=lambda s: print(s, flush=True), command=[sys.executable, *sys.argv])
    if args.copy:
        name = f"paper_size_{args.setting}_{args.seeds}seed"
        shutil.copyfile(out / "table1.md", HERE / "results" / f"{name}.md")
        shutil.copyfile(out / "results.json", HERE / "results" / f"{name}.json")


if __name__ == "__main__":
    main()
