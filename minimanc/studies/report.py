"""Chapter 9 — the report of a study: :func:`findings` checks each of the paper's claims
on the numbers, :func:`table_markdown` writes ``table1.md`` (Table I per setting, the
studies as tables, the findings), and :func:`json_safe` prepares ``results.json``."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np


def _mean(agg: dict, metric: str) -> float:
    return float(agg[metric]["mean"])


def _std(agg: dict, metric: str) -> float:
    return float(agg[metric]["std"])


def _noise(a: dict, b: dict, metric: str) -> str:
    """A note when two means differ by less than their combined seed std."""
    d = abs(_mean(a, metric) - _mean(b, metric))
    s = _std(a, metric) + _std(b, metric)
    if a[metric]["n"] > 1 and d < s:
        return f" (difference {d:.2f} is within the seed spread {s:.2f})"
    return ""


def _fmt(x: float) -> str:
    return f"{x:.2f}"


def findings(results: dict) -> list[dict]:
    """The paper's claims, checked on ``results``: ``[{"id", "claim", "holds", "detail"}]``.

    ``holds`` is ``True``/``False`` (``None`` when the study lacks the pieces);
    ``detail`` quotes the numbers.  Nothing here is hard-coded: every sentence
    is computed from ``results``.
    """
    out: list[dict] = []

    def add(id_: str, claim: str, holds: bool | None, detail: str) -> None:
        out.append({"id": id_, "claim": claim, "holds": holds, "detail": detail})

    names = lambda ms: ", ".join(f"{m} {v}" for m, v in ms)  # noqa: E731
    for setting, table in results.get("table1", {}).items():
        learned = [m for m in table if m != "human"]
        if "manc" not in learned or len(learned) < 2:
            continue
        others = [m for m in learned if m != "manc"]
        for metric, word in (("ade", "ADE (human driving similarity)"),
                             ("goal_distance", "goal distance")):
            vals = {m: _mean(table[m], metric) for m in learned}
            best = min(vals, key=vals.get)
            runner = min(others, key=vals.get)
            add(f"manc_best_{metric}_{setting}",
                f"MANC has the best {word} ({setting} setting)", best == "manc",
                f"{metric}: " + names((m, _fmt(vals[m])) for m in learned)
                + f"; best is {best}"
                + (_noise(table["manc"], table[runner], metric) if best == "manc"
                   else _noise(table["manc"], table[best], metric)))
        human = table["human"]
        for metric, word in (("close_encounters", "% close encounters"),
                             ("max_acceleration", "maximum acceleration")):
            h = _mean(human, metric)
            dist = {m: abs(_mean(table[m], metric) - h) for m in learned}
            closest = min(dist, key=dist.get)
            add(f"manc_near_human_{metric}_{setting}",
                f"MANC's {word} is the closest to the human's ({setting} setting)",
                closest == "manc",
                f"human {_fmt(h)}; " + names((m, _fmt(_mean(table[m], metric)))
                                             for m in learned) + f"; closest is {closest}")
    t1 = results.get("table1", {})
    if "paper" in t1 and "parity" in t1:
        parts, gains = [], []
        for m in t1["paper"]:
            if m in ("human", "manc") or m not in t1["parity"]:
                continue
            a, b = _mean(t1["paper"][m], "ade"), _mean(t1["parity"][m], "ade")
            parts.append(f"{m} {_fmt(a)} → {_fmt(b)}")
            gains.append(b < a)
        if parts:
            add("parity_helps_baselines",
                "Giving the baselines the lane target and their motion (parity) lowers their ADE",
                all(gains), "ADE paper → parity: " + "; ".join(parts))
    prior = results.get("references", {}).get("dmp_prior")
    manc_rows = [t["manc"] for t in results.get("table1", {}).values() if "manc" in t]
    if prior and manc_rows:
        m, p = _mean(manc_rows[0], "ade"), _mean(prior, "ade")
        add("learning_beats_prior",
            "Learning the gains (MANC) imitates better than the DMP head at fixed gains "
            "(not a claim of the paper: the bar the learned part must clear)", m < p,
            f"ADE: MANC {_fmt(m)}, DMP at fixed gains {_fmt(p)}; goal distance: MANC "
            f"{_fmt(_mean(manc_rows[0], 'goal_distance'))}, fixed gains "
            f"{_fmt(_mean(prior, 'goal_distance'))}")
    qs = results.get("q_states")
    if qs and len(qs["n_states"]) >= 2:
        n = qs["n_states"]
        ade = [_mean(a, "ade") for a in qs["results"]]
        mono = all(b <= a for a, b in zip(ade, ade[1:]))
        rho = _spearman(n, ade)
        add("q_states_ade", "More q-states give a better (lower) ADE",
            bool(ade[-1] < ade[0]),
            "ADE by number of q-states: " + names((k, _fmt(v)) for k, v in zip(n, ade))
            + f"; {'monotone' if mono else 'not monotone'}, Spearman ρ(n, ADE) = {rho:.2f}")
    ab = results.get("ablation", {}).get("models", {})
    if {"manc", "dmp_only"} <= set(ab):
        m, d = ab["manc"], ab["dmp_only"]
        agg = (_mean(d, "max_acceleration") > _mean(m, "max_acceleration")
               and _mean(d, "close_encounters") > _mean(m, "close_encounters"))
        add("ablation_dmp_only_aggressive",
            "DMP-only drives more aggressively than MANC (higher acceleration and "
            "close encounters)", agg,
            f"max |a|: DMP-only {_fmt(_mean(d, 'max_acceleration'))}, MANC "
            f"{_fmt(_mean(m, 'max_acceleration'))}; close encounters: DMP-only "
            f"{_fmt(_mean(d, 'close_encounters'))} %, MANC {_fmt(_mean(m, 'close_encounters'))} %")
    if {"vagn_only", "dmp_only"} <= set(ab):
        v, d = ab["vagn_only"], ab["dmp_only"]
        safer = (_mean(v, "max_acceleration") < _mean(d, "max_acceleration")
                 and _mean(v, "close_encounters") < _mean(d, "close_encounters"))
        add("ablation_vagn_only_safer",
            "vAGN-only is safer than DMP-only (lower acceleration and close encounters)", safer,
            f"max |a|: vAGN-only {_fmt(_mean(v, 'max_acceleration'))}, DMP-only "
            f"{_fmt(_mean(d, 'max_acceleration'))}; close encounters: vAGN-only "
            f"{_fmt(_mean(v, 'close_encounters'))} %, DMP-only "
            f"{_fmt(_mean(d, 'close_encounters'))} %")
    if {"vagn_only", "manc"} <= set(ab):
        v, m = ab["vagn_only"], ab["manc"]
        worse = (_mean(v, "ade") > _mean(m, "ade")
                 and _mean(v, "goal_distance") > _mean(m, "goal_distance"))
        add("ablation_vagn_only_worse_goal",
            "vAGN-only reaches the goal worse and imitates worse than MANC", worse,
            f"ADE: vAGN-only {_fmt(_mean(v, 'ade'))}, MANC {_fmt(_mean(m, 'ade'))}; goal "
            f"distance: vAGN-only {_fmt(_mean(v, 'goal_distance'))}, MANC "
            f"{_fmt(_mean(m, 'goal_distance'))}")
    se = results.get("sample_efficiency")
    if se and "manc" in se["models"] and len(se["models"]) > 1:
        i = 0
        f0 = se["fractions"][i]
        vals = {m: _mean(a[i], "ade") for m, a in se["models"].items()}
        best = min(vals, key=vals.get)
        add("sample_efficiency",
            f"With {round(100 * f0)} % of the training data MANC has the lowest ADE",
            best == "manc",
            f"ADE at {round(100 * f0)} %: " + names((m, _fmt(v)) for m, v in vals.items()))
    pc = results.get("param_counts", {}).get("paper")
    if pc and "manc" in pc:
        others = {m: pc[m] for m in ("cnn", "cnn_lstm", "rvs_g") if m in pc}
        if others:
            ratio = {m: 1 - pc["manc"] / v for m, v in others.items()}
            add("param_counts",
                "MANC has at least 30 % fewer parameters than each comparison model",
                all(r >= 0.3 for r in ratio.values()),
                f"MANC {pc['manc']:,}; " + ", ".join(
                    f"{m} {v:,} (MANC has {abs(100 * ratio[m]):.0f} % "
                    f"{'fewer' if ratio[m] >= 0 else 'more'})" for m, v in others.items()))
    return out


def _spearman(x: Sequence[float], y: Sequence[float]) -> float:
    rx = np.argsort(np.argsort(x)).astype(float)
    ry = np.argsort(np.argsort(y)).astype(float)
    if rx.std() == 0 or ry.std() == 0:
        return 0.0
    return float(np.corrcoef(rx, ry)[0, 1])


_COLS = ("close_encounters", "max_acceleration", "ade", "goal_distance", "collision_rate",
         "off_road_rate")
_HEAD = ("% close encounters", "max \\|a\\| (m/s²)", "ADE (m)", "goal distance (m)",
         "% collisions", "% off road")


def cell(agg: dict, metric: str, n_seeds: int) -> str:
    e = agg.get(metric)
    if e is None:
        return "n/a"
    if not np.isfinite(e["mean"]):
        return "diverged"
    return f"{e['mean']:.2f} ± {e['std']:.2f}" if n_seeds > 1 else f"{e['mean']:.2f}"


def _training(config: dict, key: str) -> Any:
    """A training field of a results file's ``config`` (its ``training`` entry, or the flat
    keys of a file written before the study held a TrainConfig)."""
    t = config.get("training")
    if t is None:
        return config[key]
    return t[key] if isinstance(t, dict) else getattr(t, key)


def table_markdown(results: dict) -> str:
    """``table1.md``: Table I per setting, the studies as tables, and the findings."""
    from minimanc.plots import model_label

    c = results["config"]
    ns = int(c["n_seeds"])
    lab = model_label
    lines = [
        "# Closed-loop results (Table I and the studies of section V)",
        "",
        f"Preset `{c['preset']}`: {c['n_train']} training, {c['n_tune']} tuning and "
        f"{c['n_val']} validation scenes ({c['image_size']}×{c['image_size']} BEV), "
        f"{_training(c, 'epochs')} epochs, learning rate from {list(c['lrs'])} by tuning-split "
        "ADE, "
        f"{'mean ± std over ' + str(ns) + ' seeds' if ns > 1 else 'one seed'}; "
        f"engine `{results['engine']}`. Lower is better everywhere. Close encounter: an ado "
        f"box within {results['close_gap_m']:g} m of the ego box. Human ADE and goal "
        "distance are 0 by construction (the goal is the human's final pose).",
        "",
    ]
    header = "| Model | " + " | ".join(_HEAD) + " |"
    rule = "|---" * (len(_HEAD) + 1) + "|"
    for setting, table in results["table1"].items():
        lines += [f"## Table I — setting `{setting}`", "", header, rule]
        for m, agg in table.items():
            n = 1 if m == "human" else ns
            lines.append(f"| {lab(m)} | " + " | ".join(cell(agg, k, n) for k in _COLS) + " |")
        lines.append("")
    se = results.get("sample_efficiency")
    if se:
        fr = se["fractions"]
        lines += [f"## Sample efficiency — ADE (m), setting `{se['setting']}`", "",
                  "| Model | " + " | ".join(f"{round(100 * f)} %" for f in fr) + " |",
                  "|---" * (len(fr) + 1) + "|"]
        for m, aggs in se["models"].items():
            lines.append(f"| {lab(m)} | " + " | ".join(cell(a, "ade", ns) for a in aggs) + " |")
        lines.append("")
    qs = results.get("q_states")
    if qs:
        lines += ["## MANC: number of q-states", "", "| #q | " + " | ".join(_HEAD) + " |", rule]
        for n, agg in zip(qs["n_states"], qs["results"]):
            lines.append(f"| {n} | " + " | ".join(cell(agg, k, ns) for k in _COLS) + " |")
        lines.append("")
    ab = results.get("ablation")
    if ab:
        lines += ["## Self-ablation", "", header, rule]
        for m, agg in ab["models"].items():
            lines.append(f"| {lab(m)} | " + " | ".join(cell(agg, k, ns) for k in _COLS) + " |")
        lines.append("")
    refs = results.get("references")
    if refs:
        lines += ["## Reference without learning", "",
                  "The DMP head of MANC at its initial constant gains, no network (eqs. 10–11 "
                  "with a constant in place of FC(q)): what the structure alone achieves.", "",
                  header, rule]
        for m, agg in refs.items():
            lines.append(f"| {lab(m)} | " + " | ".join(cell(agg, k, 1) for k in _COLS) + " |")
        lines.append("")
    pc = results.get("param_counts")
    if pc:
        settings = list(pc)
        models_ = list(pc[settings[0]])
        lines += ["## Parameters", "", "| Model | " + " | ".join(settings) + " |",
                  "|---" * (len(settings) + 1) + "|"]
        for m in models_:
            lines.append(f"| {lab(m)} | " + " | ".join(f"{pc[s][m]:,}" for s in settings) + " |")
        lines.append("")
    if results.get("lr"):
        lines += ["## Learning rates (best closed-loop ADE on the tuning split)", ""]
        lines += [f"- {k}: {v:g}" for k, v in results["lr"].items()]
        lines.append("")
    lines += ["## The paper's claims, checked", ""]
    if ns == 1:
        lines += ["With one seed the seed-to-seed spread is unknown: small differences below "
                  "may be noise (`minimanc reproduce --seeds 3`).", ""]
    for f in results.get("findings", []):
        mark = {True: "holds", False: "does NOT hold", None: "not tested"}[f["holds"]]
        lines.append(f"- **{f['claim']}** — {mark}. {f['detail']}.")
    lines.append("")
    return "\n".join(lines)


def json_safe(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {str(k): json_safe(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [json_safe(v) for v in obj]
    if isinstance(obj, np.floating | float):
        x = float(obj)
        return x if np.isfinite(x) else None
    if isinstance(obj, np.integer):
        return int(obj)
    return obj
