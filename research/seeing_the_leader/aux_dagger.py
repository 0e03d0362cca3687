"""Does the auxiliary perception loss help once it also trains on DAgger's states? The CNN
in the learner's adopted form (``end_to_end.py``'s ``speed_dagger_warm2``: the learner's
raster, its own speed and lane target as numbers, DAgger 10 rounds each continuing 2 epochs)
against the same form with the masked auxiliary loss at λ = 1 on the demonstrations and on
every collected state (``speed_dagger_warm2_aux``: the teacher records what the human
perceives in each state it labels, :func:`minimanc.diagnose.state_targets`), and that with
the perception study's four-layer backbone (``speed_dagger_warm2_aux_deep``: 32, 64, 64 and
64 channels where the course's CNN has 16, 32 and 32), whose own read-out reads the gap to
2.66 m when trained on perception alone (``results/perception.md``, ``route60_scale``); the
CNN-LSTM and RvS-G in that form too, against their DAgger form in ``end_to_end.md``. MANC
in the library's learner form (``manc_qp`` in ``dagger_flat_warm2_p64_goal10``: eq. 7 over
the flattened features, 64 predicates, gains over q ⊕ p, the DMP's goal 10 m ahead)
against the same with the auxiliary loss and the four-layer backbone
(``dagger_flat_warm2_p64_goal10_aux_deep``).

Protocol (``end_to_end.py``'s, fixed before any number of the new form was seen): train on
scenes 0–599 of the seed-0 draw, drive the validation scenes 600–799 among reactive and
replayed ados; probe the backbone's flattened features (``probe_models.py``: ridge, every
third training scene, scored on the validation scenes; the gap and closing speed of leaders
within 30 m, whether there is a leader in the view, the own speed). λ = 1 is the value the
behaviour-cloned study fixed beforehand (``aux_loss.py``). The λ = 0 rows and the bounds are
quoted from the committed ``results/end_to_end.md`` and ``results/probe_models.md`` (their
runs are not repeated here).

Run: ``SEEING_DATA=/path python research/seeing_the_leader/aux_dagger.py --seeds 0 1 2
--forms speed_dagger_warm2_aux --work runs/end_to_end`` (each form's models, or ``--models``;
every run and probe cached as JSON under ``--work``; a finished one is not repeated); writes
``results/aux_dagger.md`` from every cached run, whichever ``--seeds`` trained.
"""

from __future__ import annotations

import argparse
import json
import re
import time
from pathlib import Path

import end_to_end as E
import leader_data as L
import numpy as np
import probe_models as P

from minimanc.studies import provenance

AUX_RUNS = {("cnn", "speed_dagger_warm2_aux"): "speed_dagger_warm2",
            ("cnn", "speed_dagger_warm2_aux_deep"): "speed_dagger_warm2",
            ("cnn_lstm", "speed_dagger_warm2_aux_deep"): "speed_dagger",
            ("rvs_g", "speed_dagger_warm2_aux_deep"): "speed_dagger",
            ("manc_qp", "dagger_flat_warm2_p64_goal10_aux_deep"): "dagger_flat_warm2_p64_goal10"}
"""Each model in a form with the auxiliary loss on DAgger's states, and the form it is measured
against (λ = 0; for CNN-LSTM and RvS-G the form ``end_to_end.md`` has, whose rounds train from
the start)."""
WEIGHT = 1.0
OUT = E.RESULTS / "aux_dagger.md"
METRICS = (("at_fault_collision_rate", "at fault %", 1), ("collision_rate", "coll. %", 1),
           ("ade", "ADE m", 2), ("route_progress", "progress", 2))
PROBES = (("gap_rmse", "gap m (≤ 30 m)", 2), ("dv_rmse", "dv m/s (≤ 30 m)", 2),
          ("lead_accuracy", "leader in view %", 1), ("v_rmse", "own speed m/s", 2))


def quoted(path: Path, starts: tuple[str, ...]) -> list[str]:
    """The table rows of ``path`` that start with one of ``starts``, each under its section's
    ``## `` head (as ``### ``) and its table's header; a row already quoted is not repeated."""
    out: list[str] = []
    lines = path.read_text().splitlines()
    head, header, shown = "", [], set()
    for i, line in enumerate(lines):
        if line.startswith("## "):
            head = line
        elif line.startswith("|") and i + 1 < len(lines) and lines[i + 1].startswith("|---"):
            header = [line, lines[i + 1]]
        elif line.startswith(starts) and line not in shown:
            shown.add(line)
            if head not in shown:
                out += ["", "#" + head, ""] if head else [""]
                shown.add(head)
            if (head, header[0]) not in shown:
                out += header
                shown.add((head, header[0]))
            out.append(line)
    return out


def runs(work: Path, model: str, form: str) -> list[dict]:
    """Every cached closed-loop run of ``model`` in ``form``, whichever seeds have one."""
    rows = []
    for agents in E.AGENTS:
        name = re.compile(rf"{re.escape(f'{model}_{form}')}_s\d+_{agents}\.json")
        paths = (work / "runs").glob(f"{model}_{form}_s*_{agents}.json")
        rows += [json.loads(p.read_text()) for p in sorted(paths) if name.fullmatch(p.name)]
    return rows


def drive_table(rows: list[dict]) -> list[str]:
    lines = ["| agents | seed | " + " | ".join(k[1] for k in METRICS) + " |",
             "|---|---|" + "---|" * len(METRICS)]
    for r in sorted(rows, key=lambda r: (E.AGENTS.index(r["agents"]), r["seed"])):
        cells = [f"{r['metrics'][k]:.{d}f}" for k, _, d in METRICS]
        lines.append(f"| {r['agents']} | {r['seed']} | " + " | ".join(cells) + " |")
    for agents in E.AGENTS:
        rs = [r for r in rows if r["agents"] == agents]
        if len(rs) > 1:
            cells = [E.cell([r["metrics"][k] for r in rs], d) for k, _, d in METRICS]
            lines.append(f"| {agents} | mean ± std ({len(rs)}) | " + " | ".join(cells) + " |")
    return lines


def probe_table(rows: list[dict]) -> list[str]:
    lines = ["| seed | " + " | ".join(k[1] for k in PROBES) + " |",
             "|---|" + "---|" * len(PROBES)]
    for r in sorted(rows, key=lambda r: r["seed"]):
        cells = [f"{r[k] * (100 if k == 'lead_accuracy' else 1):.{d}f}" for k, _, d in PROBES]
        lines.append(f"| {r['seed']} | " + " | ".join(cells) + " |")
    return lines


def report(work: Path) -> str:
    lines = ["# The auxiliary perception loss on DAgger's states\n",
             __doc__.split("\n\n")[0].replace("\n", " ") + "\n",
             __doc__.split("\n\n")[1].replace("\n", " ") + "\n"]
    for model in dict.fromkeys(m for m, _ in AUX_RUNS):
        lines += model_report(work, model)
    return "\n".join(lines) + "\n"


def model_report(work: Path, model: str) -> list[str]:
    """The sections of ``model``'s forms: closed loop and probe, then the quoted λ = 0 form
    and the bounds."""
    lines: list[str] = []
    forms = [f for m, f in AUX_RUNS if m == model]
    for form in forms:
        driven = runs(work, model, form)
        if not driven:
            continue
        text = E.form_text(form, WEIGHT)
        done = sorted({r["seed"] for r in driven})  # trained: their probes can be run
        probes = [r for s in done for r in P.run(model, form, s, work)
                  if r["what"] == "features"]
        lines += [f"## {model}, {text}: closed loop on the validation scenes\n",
                  *drive_table(driven), "",
                  f"## {model}, {text}: a probe of its features\n", *probe_table(probes), ""]
    if not lines:
        return lines
    base = AUX_RUNS[model, forms[0]]
    text = E.form_text(base, WEIGHT)
    probe = quoted(E.RESULTS / "probe_models.md", (f"| {model} | {text} |",))
    return lines + [f"## Quoted: {model}, {text}, and the bounds (`end_to_end.md`)",
                    *quoted(E.RESULTS / "end_to_end.md",
                            (f"| {model}, {text} |", f"| {model} | {text} |", "| Expert",
                             "| Style floor", "| DMP at fixed", "| Privileged")),
                    "", f"## Quoted: the probe of {model}, {text} (`probe_models.md`)",
                    *(probe or ["", "Not measured: `probe_models.md` has no row of this form."]),
                    ""]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[0])
    ap.add_argument("--forms", nargs="+", choices=sorted({f for _, f in AUX_RUNS}),
                    default=[next(iter(AUX_RUNS))[1]])
    ap.add_argument("--models", nargs="+", choices=sorted({m for m, _ in AUX_RUNS}),
                    help="of the forms' models, only these (default: all)")
    ap.add_argument("--work", type=Path, default=L.DATA_DIR / "end_to_end")
    ap.add_argument("--report", action="store_true",
                    help="only write results/aux_dagger.md (from every cached run)")
    args = ap.parse_args()
    if any(s < 0 for s in args.seeds):
        raise SystemExit(f"--seeds must be >= 0, got {args.seeds}")
    t0 = time.perf_counter()
    if not args.report:
        for seed in args.seeds:
            for model, form in AUX_RUNS:
                if form not in args.forms or (args.models and model not in args.models):
                    continue
                E.run_model(model, form, seed, WEIGHT, args.work)
                P.run(model, form, seed, args.work)
    provenance.publish(report(args.work), str(OUT), time.perf_counter() - t0)
    print(np.round(time.perf_counter() - t0), "s")


if __name__ == "__main__":
    main()
