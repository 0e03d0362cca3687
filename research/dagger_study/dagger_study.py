"""Chapter 11 study: behaviour cloning against DAgger at equal expert-labelled samples.

For each simulator (the world under reactive and under replayed ados, highway-env's
roundabout), each model (MANC, the CNN) and each seed, runs ``minimanc dagger`` (3 DAgger
rounds after the demonstrations, β_i = 0.5^i, and BC on the same number of labels) and
writes the mean ± std over seeds of BC and of DAgger's last round, and DAgger's ADE per
round, with the run's provenance, to ``--out`` (markdown, quoted by the README) and the
per-run numbers to the JSON beside it.

    python research/dagger_study/dagger_study.py [--seeds 3] \
        [--out research/dagger_study/results/dagger_study.md]

Each run keeps its checkpoints under ``--work`` (default ``runs/dagger_study``): a rerun
after an interruption resumes where it stopped.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from minimanc import cli
from minimanc.studies import provenance

WORLD = ["--sim", "world", "--scenes", "32", "--val-scenes", "16"]
SIMS = {
    "world, reactive ados": ("world-reactive", [*WORLD, "--agents", "reactive"]),
    "world, replayed ados": ("world-replay", [*WORLD, "--agents", "replay"]),
    "highway-env roundabout": ("highway-roundabout",
                               ["--sim", "highway", "--scenario", "roundabout", "--scenes", "12",
                                "--val-scenes", "6", "--steps", "20"]),
}
"""Label -> (run folder prefix, the simulator's options of ``minimanc dagger``)."""
METRICS = {"ade": "ADE (m)", "collision_rate": "% collisions",
           "at_fault_collision_rate": "% at fault", "off_road_rate": "% off road"}
MODELS = ("manc", "cnn")


def run(sim: str, model: str, seed: int, work: Path) -> dict:
    slug, options = SIMS[sim]
    out = work / f"{slug}-{model}-s{seed}"
    argv = ["dagger", "--model", model, "--rounds", "3", "--beta", "0.5", "--seed", str(seed),
            "--size", "32", "--epochs", "4", "--out", str(out), "--quiet", *options]
    code = cli.main(argv)
    if code != 0:
        raise SystemExit(f"minimanc {' '.join(argv)} exited with {code}")
    return json.loads((out / "dagger.json").read_text())


def cell(values: list[float]) -> str:
    v = np.asarray(values, dtype=np.float64)
    if not np.all(np.isfinite(v)):
        return "n/a"
    return f"{v.mean():.1f} ± {v.std():.1f}" if v.size > 1 else f"{v.mean():.1f}"


def markdown(runs: dict, seeds: int, seconds: float) -> str:
    lines = ["# Behaviour cloning against DAgger at equal labels", ""]
    for sim, per_model in runs.items():
        keys = [k for k in METRICS
                if all(k in r["rounds"][-1]["metrics"] for rs in per_model.values() for r in rs)]
        first = next(iter(per_model.values()))[0]
        lines += [f"## {sim}", "",
                  f"{len(first['rounds']) - 1} DAgger rounds after the demonstrations "
                  f"(β = 1, 0.5, 0.25, 0.125), {first['rounds'][-1]['labelled']} expert-labelled "
                  f"samples for both methods; mean ± std over {seeds} seeds.", "",
                  "| model | method | " + " | ".join(METRICS[k] for k in keys) + " |",
                  "|---" * (len(keys) + 2) + "|"]
        for model, rs in per_model.items():
            bc = [r["bc"]["metrics"] for r in rs]
            dg = [r["rounds"][-1]["metrics"] for r in rs]
            for method, ms in (("BC", bc), ("DAgger", dg)):
                lines.append(f"| {model} | {method} | "
                             + " | ".join(cell([m[k] for m in ms]) for k in keys) + " |")
        lines += ["", "DAgger's ADE (m) by round:", "",
                  "| model | " + " | ".join(f"round {r['round']}" for r in first["rounds"])
                  + " |", "|---" * (len(first["rounds"]) + 1) + "|"]
        for model, rs in per_model.items():
            lines.append(f"| {model} | " + " | ".join(
                cell([r["rounds"][i]["metrics"]["ade"] for r in rs])
                for i in range(len(first["rounds"]))) + " |")
        lines.append("")
    return "\n".join(lines) + "\n" + provenance.provenance_markdown(provenance.provenance(),
                                                                 wall_time_s=seconds)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--out", default="research/dagger_study/results/dagger_study.md")
    ap.add_argument("--work", default="runs/dagger_study")
    args = ap.parse_args()
    t0 = time.perf_counter()
    runs: dict = {}
    for sim in SIMS:
        runs[sim] = {}
        for model in MODELS:
            runs[sim][model] = []
            for seed in range(args.seeds):
                runs[sim][model].append(run(sim, model, seed, Path(args.work)))
                print(f"{sim} {model} seed {seed}: done at "
                      f"{(time.perf_counter() - t0) / 60:.1f} min", flush=True)
    out = Path(args.out)
    provenance.write_text(out, markdown(runs, args.seeds, time.perf_counter() - t0))
    provenance.write_text(out.with_suffix(".json"), json.dumps(runs, indent=1) + "\n")
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
