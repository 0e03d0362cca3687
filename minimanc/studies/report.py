"""Chapter 9 — the report of a study: :func:`findings` checks each of the paper's claims
on the numbers, under each protocol of the ados, :func:`table_markdown` writes
``table1.md`` (Table I per protocol and setting, per scenario family, the studies as
tables, whether vAGN's q-states are driving modes, the findings), and :func:`json_safe`
prepares ``results.json``."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from minimanc import models, world
from minimanc.diagnose.bounds import BOUND_ROWS
from minimanc.studies.config import dagger_text, model_text, perception_text, raster_text
from minimanc.studies.dagger_study import dagger_markdown
from minimanc.studies.provenance import provenance_markdown
from minimanc.viz.style import model_label


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


REFERENCE_ROWS: tuple[str, ...] = ("human", "dmp_prior", *BOUND_ROWS)
"""Table I's rows that are not learned models: the logged human, the DMP head at fixed
gains (:func:`minimanc.rollout.fixed_gains`) and the bounds (:mod:`minimanc.diagnose.bounds`:
the expert, the style floor, the privileged learner)."""

MODE_MIN_EXCESS: float = 0.05
"""The explainability claim holds for a model when the mutual information between its most
likely q-state and the human's mode exceeds the shuffled-scene baseline's 95th percentile
and its mean by at least this many bits (:func:`minimanc.metrics.modes.mode_information`)."""


def protocols(results: dict) -> dict:
    """``{agents: {setting: {model: aggregate}}}`` of ``results["table1"]`` (a results file
    written before Table I had protocols, ``{setting: ...}``, is the ``"replay"`` one)."""
    t1 = results.get("table1", {})
    if t1 and all("human" in t for t in t1.values()):
        return {"replay": t1}
    return t1


def _prior(results: dict, agents: str, table: dict) -> dict | None:
    if "dmp_prior" in table:
        return table["dmp_prior"]
    refs = results.get("references", {})
    return refs.get("dmp_prior") if agents == "replay" else None


def findings(results: dict) -> list[dict]:
    """The paper's claims, checked on ``results``: ``[{"id", "claim", "holds", "detail"}]``.

    ``holds`` is ``True``/``False`` (``None`` when the study lacks the pieces);
    ``detail`` quotes the numbers.  Nothing here is hard-coded: every sentence
    is computed from ``results``.  A claim on Table I is checked under each protocol
    of the ados (its ``agents`` entry); when it holds under one and not the other,
    both details say so.
    """
    out: list[dict] = []

    def add(id_: str, claim: str, holds: bool | None, detail: str,
            agents: str | None = None) -> None:
        f = {"id": id_, "claim": claim, "holds": holds, "detail": detail}
        if agents is not None:
            f["agents"] = agents
        out.append(f)

    names = lambda ms: ", ".join(f"{m} {v}" for m, v in ms)  # noqa: E731
    for agents, t1 in protocols(results).items():
        _table_claims(results, agents, t1, add, names)
    _protocol_notes(out)
    _study_claims(results, add, names)
    return out


def _protocol_notes(out: list[dict]) -> None:
    """Tell, in each detail, when a claim holds under one protocol and not the other."""
    groups: dict[str, list[dict]] = {}
    for f in out:
        if "agents" in f:
            groups.setdefault(f["id"][: -len(f["agents"]) - 1], []).append(f)
    for fs in groups.values():
        if len({f["holds"] for f in fs}) > 1:
            yes = [f["agents"] for f in fs if f["holds"]]
            no = [f["agents"] for f in fs if not f["holds"]]
            note = (f"; holds under {', '.join(yes)} agents and not under {', '.join(no)}: "
                    "the protocol decides")
            for f in fs:
                f["detail"] += note


def _table_claims(results: dict, agents: str, t1: dict, add: Any, names: Any) -> None:
    word_a = f"{agents} agents"
    for setting, table in t1.items():
        learned = [m for m in table if m not in REFERENCE_ROWS]
        if "manc" not in learned or len(learned) < 2:
            continue
        others = [m for m in learned if m != "manc"]
        for metric, word in (("ade", "ADE (human driving similarity)"),
                             ("goal_distance", "goal distance")):
            vals = {m: _mean(table[m], metric) for m in learned}
            best = min(vals, key=vals.get)
            runner = min(others, key=vals.get)
            add(f"manc_best_{metric}_{setting}_{agents}",
                f"MANC has the best {word} ({setting} setting, {word_a})", best == "manc",
                f"{metric}: " + names((m, _fmt(vals[m])) for m in learned)
                + f"; best is {best}"
                + (_noise(table["manc"], table[runner], metric) if best == "manc"
                   else _noise(table["manc"], table[best], metric)), agents)
        human = table["human"]
        for metric, word in (("close_encounters", "% close encounters"),
                             ("max_acceleration", "maximum acceleration")):
            h = _mean(human, metric)
            dist = {m: abs(_mean(table[m], metric) - h) for m in learned}
            closest = min(dist, key=dist.get)
            add(f"manc_near_human_{metric}_{setting}_{agents}",
                f"MANC's {word} is the closest to the human's ({setting} setting, {word_a})",
                closest == "manc",
                f"human {_fmt(h)}; " + names((m, _fmt(_mean(table[m], metric)))
                                             for m in learned) + f"; closest is {closest}",
                agents)
        if all("along_track" in table[m] for m in learned):
            along = {m: _mean(table[m], "along_track") for m in learned}
            cross = {m: _mean(table[m], "cross_track") for m in learned}
            add(f"error_is_along_track_{setting}_{agents}",
                "The imitation error is mostly along the road (speed and timing), not across "
                f"it (steering), for every model ({setting} setting, {word_a}; not a claim "
                "of the paper: where the ADE comes from)",
                all(along[m] > cross[m] for m in learned),
                "mean |along-track| / |cross-track| error (m): " + names(
                    (m, f"{_fmt(along[m])} / {_fmt(cross[m])} (bias "
                        f"{_fmt(_mean(table[m], 'along_bias'))})") for m in learned)
                + "; a negative bias is behind the human", agents)
    if "human" in next(iter(t1.values()), {}) and agents == "reactive":
        h = next(iter(t1.values()))["human"]
        if "at_fault_collision_rate" in h:
            a, c = _mean(h, "at_fault_collision_rate"), _mean(h, "collision_rate")
            add("reactive_human_no_at_fault",
                "The human's logged controls among reactive ados have no at-fault collision "
                "(a check of the reactive simulator, not a claim of the paper)", a == 0.0,
                f"human under reactive agents: {_fmt(a)} % of scenes with an at-fault "
                f"collision, {_fmt(c)} % with any collision")
    if "paper" in t1 and "parity" in t1:
        parts, gains = [], []
        for m in t1["paper"]:
            if m in (*REFERENCE_ROWS, "manc") or m not in t1["parity"]:
                continue
            a, b = _mean(t1["paper"][m], "ade"), _mean(t1["parity"][m], "ade")
            parts.append(f"{m} {_fmt(a)} → {_fmt(b)}")
            gains.append(b < a)
        if parts:
            add(f"parity_helps_baselines_{agents}",
                "Giving the baselines the lane target and their motion (parity) lowers their "
                f"ADE ({word_a})", all(gains), "ADE paper → parity: " + "; ".join(parts),
                agents)
    first = next(iter(t1.values()), {})
    prior = _prior(results, agents, first)
    if prior and "manc" in first:
        manc = first["manc"]
        m, p = _mean(manc, "ade"), _mean(prior, "ade")
        add(f"learning_beats_prior_{agents}",
            "Learning the gains (MANC) imitates better than the DMP head at fixed gains "
            f"({word_a}; not a claim of the paper: the bar the learned part must clear)",
            m < p,
            f"ADE: MANC {_fmt(m)}, DMP at fixed gains {_fmt(p)}; goal distance: MANC "
            f"{_fmt(_mean(manc, 'goal_distance'))}, fixed gains "
            f"{_fmt(_mean(prior, 'goal_distance'))}", agents)


def _study_claims(results: dict, add: Any, names: Any) -> None:
    def under(study: dict) -> str:
        return f", {study['agents']} agents" if "agents" in study else ""

    qs = results.get("q_states")
    if qs and len(qs["n_states"]) >= 2:
        n = qs["n_states"]
        ade = [_mean(a, "ade") for a in qs["results"]]
        mono = all(b <= a for a, b in zip(ade, ade[1:]))
        rho = _spearman(n, ade)
        add("q_states_ade", f"More q-states give a better (lower) ADE ({qs['setting']} "
            f"setting{under(qs)})",
            bool(ade[-1] < ade[0]),
            "ADE by number of q-states: " + names((k, _fmt(v)) for k, v in zip(n, ade))
            + f"; {'monotone' if mono else 'not monotone'}, Spearman ρ(n, ADE) = {rho:.2f}")
    ab_study = results.get("ablation", {})
    ab = ab_study.get("models", {})
    u = under(ab_study)
    paren = f" ({ab_study['agents']} agents)" if "agents" in ab_study else ""
    if {"manc", "dmp_only"} <= set(ab):
        m, d = ab["manc"], ab["dmp_only"]
        agg = (_mean(d, "max_acceleration") > _mean(m, "max_acceleration")
               and _mean(d, "close_encounters") > _mean(m, "close_encounters"))
        add("ablation_dmp_only_aggressive",
            "DMP-only drives more aggressively than MANC (higher acceleration and "
            f"close encounters{u})", agg,
            f"max |a|: DMP-only {_fmt(_mean(d, 'max_acceleration'))}, MANC "
            f"{_fmt(_mean(m, 'max_acceleration'))}; close encounters: DMP-only "
            f"{_fmt(_mean(d, 'close_encounters'))} %, MANC {_fmt(_mean(m, 'close_encounters'))} %")
    if {"vagn_only", "dmp_only"} <= set(ab):
        v, d = ab["vagn_only"], ab["dmp_only"]
        safer = (_mean(v, "max_acceleration") < _mean(d, "max_acceleration")
                 and _mean(v, "close_encounters") < _mean(d, "close_encounters"))
        add("ablation_vagn_only_safer",
            f"vAGN-only is safer than DMP-only (lower acceleration and close encounters{u})",
            safer,
            f"max |a|: vAGN-only {_fmt(_mean(v, 'max_acceleration'))}, DMP-only "
            f"{_fmt(_mean(d, 'max_acceleration'))}; close encounters: vAGN-only "
            f"{_fmt(_mean(v, 'close_encounters'))} %, DMP-only "
            f"{_fmt(_mean(d, 'close_encounters'))} %")
    if {"vagn_only", "manc"} <= set(ab):
        v, m = ab["vagn_only"], ab["manc"]
        worse = (_mean(v, "ade") > _mean(m, "ade")
                 and _mean(v, "goal_distance") > _mean(m, "goal_distance"))
        add("ablation_vagn_only_worse_goal",
            f"vAGN-only reaches the goal worse and imitates worse than MANC{paren}",
            worse,
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
            f"With {round(100 * f0)} % of the training data MANC has the lowest ADE"
            + (f" ({se['agents']} agents)" if "agents" in se else ""),
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
    md = results.get("modes", {})
    for m, agg in md.get("models", {}).items():
        mi, base = _mean(agg, "mi_bits"), _mean(agg, "shuffled_mi_bits")
        p95, h = _mean(agg, "shuffled_mi_p95"), _mean(agg, "mode_entropy_bits")
        holds = mi > p95 and mi - base >= MODE_MIN_EXCESS
        add(f"vagn_modes_{m}",
            f"vAGN learns semantically meaningful driving modes ({m}, open loop on the "
            f"validation scenes, {md.get('setting', 'paper')} setting)", holds,
            f"q's most likely state carries {mi:.3f} bits about the human's mode (of "
            f"{h:.3f} bits in the modes), the shuffled-scene baseline {base:.3f} (95th "
            f"percentile {p95:.3f}); q changes by {_mean(agg, 'q_change'):.2f} per step "
            f"(total variation) and its most likely state switches at "
            f"{100 * _mean(agg, 'switch_rate'):.0f} % of the steps; the paper's claim "
            f"{'holds' if holds else 'does not hold'} (rule: above the baseline's 95th "
            f"percentile and at least {MODE_MIN_EXCESS:g} bits above its mean)")


def _spearman(x: Sequence[float], y: Sequence[float]) -> float:
    rx = np.argsort(np.argsort(x)).astype(float)
    ry = np.argsort(np.argsort(y)).astype(float)
    if rx.std() == 0 or ry.std() == 0:
        return 0.0
    return float(np.corrcoef(rx, ry)[0, 1])


_COLS = ("close_encounters", "max_acceleration", "ade", "goal_distance", "collision_rate",
         "at_fault_collision_rate", "ttc_rate", "route_progress", "along_track", "cross_track",
         "off_road_rate")
_HEAD = ("% close encounters", "max \\|a\\| (m/s²)", "ADE (m)", "goal distance (m)",
         "% collisions", "% at fault", "% TTC < 1 s", "route progress", "along-track (m)",
         "cross-track (m)", "% off road")
_FAMILY_LABELS = {"free": "free road", "junction": "junction", "roundabout": "roundabout",
                  "cut_in": "cut-in"}


def cell(agg: dict, metric: str, n_seeds: int) -> str:
    e = agg.get(metric)
    if e is None:
        return "n/a"
    if not np.isfinite(e["mean"]):
        return "diverged"
    return f"{e['mean']:.2f} ± {e['std']:.2f}" if n_seeds > 1 else f"{e['mean']:.2f}"


def _percent(agg: dict, metric: str) -> dict:
    """``agg`` with ``metric``'s mean and std in percent."""
    e = agg[metric]
    return {metric: {**e, "mean": 100 * e["mean"], "std": 100 * e["std"]}}


def _training(config: dict, key: str) -> Any:
    """A training field of a results file's ``config`` (its ``training`` entry, or the flat
    keys of a file written before the study held a TrainConfig)."""
    t = config.get("training")
    if t is None:
        return config[key]
    return t[key] if isinstance(t, dict) else getattr(t, key)


def _raster(config: dict) -> world.RasterConfig:
    """The raster of a results file's ``config`` (a RasterConfig, or its fields)."""
    r = config["raster"]
    return r if isinstance(r, world.RasterConfig) else world.RasterConfig(**r)


def _model(config: dict) -> models.ModelConfig:
    """The models of a results file's ``config`` (a ModelConfig, its fields, or none: the
    library's, as before the field)."""
    m = config.get("model")
    if m is None:
        return models.ModelConfig()
    return m if isinstance(m, models.ModelConfig) else models.ModelConfig(**{
        k: tuple(v) if isinstance(v, list) else v for k, v in m.items()})


_RATIO_COLS = ("ade", "along_track", "cross_track")


def floor_ratios(table: dict, agents: str, setting: str, label: Any = str) -> list[str]:
    """Lines of the table "against the bounds": every learned row's ADE, along- and
    cross-track error as multiples of the style floor's, and its at-fault collisions next
    to the expert's (nothing when the table has no bound rows)."""
    floor, expert = table.get("style_floor"), table.get("expert")
    if floor is None or expert is None:
        return []
    out = [f"Against the bounds — setting `{setting}`, agents `{agents}`: the learned rows' "
           "errors as multiples of the style floor's (1 = as close to the human as a "
           "style-blind driver that sees road and traffic perfectly), and their at-fault "
           "collisions next to the expert's.", "",
           "| Model | ADE ÷ floor | along-track ÷ floor | cross-track ÷ floor | % at fault "
           "(expert: " + f"{_mean(expert, 'at_fault_collision_rate'):.2f}) |",
           "|---|---|---|---|---|"]
    for m, agg in table.items():
        if m in REFERENCE_ROWS and m not in ("dmp_prior", "privileged"):
            continue
        ratios = [_mean(agg, k) / max(_mean(floor, k), 1e-9) for k in _RATIO_COLS]
        out.append(f"| {label(m)} | " + " | ".join(f"{r:.2f}" for r in ratios)
                   + f" | {_mean(agg, 'at_fault_collision_rate'):.2f} |")
    return [*out, ""]


_CONTACT_COLS = ("front", "stopped_ado", "lateral", "rear", "stopped_ego", "at_fault")


def contact_table(table: dict, agents: str, setting: str, label: Any = str) -> list[str]:
    """Lines of the table "collisions by kind" (:func:`minimanc.diagnose.
    collision_taxonomy`, mean over seeds of the contacts in the validation scenes) and the
    speed at the at-fault contacts next to the human's; nothing for results without it."""
    rows = [(m, agg) for m, agg in table.items() if "contacts_at_fault" in agg]
    if not rows:
        return []
    out = [f"Collisions by kind — setting `{setting}`, agents `{agents}`: first contacts in "
           "the validation scenes (front: into the vehicle ahead; stopped ado: into a "
           "standing one; lateral: beside it; rear: hit from behind; stopped ego: hit while "
           "standing), and at the at-fault ones the ego's speed next to the human's at the "
           "same step.", "",
           "| Model | front | stopped ado | lateral | rear | stopped ego | at fault | "
           "speed at contact (m/s) | human's speed (m/s) | % faster than the human |",
           "|---" * 10 + "|"]
    for m, agg in rows:
        nums = [f"{_mean(agg, 'contacts_' + k):.1f}" for k in _CONTACT_COLS]
        speeds = [_mean(agg, f"contacts_{k}") for k in ("ego_speed", "human_speed", "faster")]
        nums += [f"{v:.2f}" if np.isfinite(v) else "—" for v in speeds[:2]]
        nums.append(f"{100 * speeds[2]:.0f}" if np.isfinite(speeds[2]) else "—")
        out.append(f"| {label(m)} | " + " | ".join(nums) + " |")
    return [*out, ""]


def table_markdown(results: dict) -> str:
    """``table1.md``: Table I per protocol and setting, per scenario family, the studies as
    tables, the q-states against the human's modes, and the findings."""
    c = results["config"]
    ns = int(c["n_seeds"])
    lab = model_label
    perception = perception_text(float(_training(c, "perception_weight")))
    on_policy = dagger_text(int(c.get("dagger_rounds", 0)), int(c.get("round_epochs", 1)),
                            len(c["lrs"]) > 1)
    model_words = model_text(_model(c))
    lines = [
        "# Closed-loop results (Table I and the studies of section V)",
        "",
        f"Preset `{c['preset']}`: {c['n_train']} training, {c['n_tune']} tuning and "
        f"{c['n_val']} validation scenes, {raster_text(_raster(c))}, "
        f"{' '.join(filter(None, (str(_training(c, 'epochs')), 'epochs', perception)))}, "
        + (f"{on_policy}, " if on_policy else "") + (f"{model_words}, " if model_words else "") +
        (f"learning rate from {list(c['lrs'])} by tuning-split ADE, " if len(c["lrs"]) > 1
         else f"learning rate {c['lrs'][0]:g}, ") +
        f"{'mean ± std over ' + str(ns) + ' seeds' if ns > 1 else 'one seed'}; "
        f"engine `{results['engine']}`. Lower is better everywhere except route progress "
        "(1 = as far along the route as the human). Close encounter: an ado "
        f"box within {results['close_gap_m']:g} m of the ego box. Human ADE and goal "
        "distance are 0 by construction (the goal is the human's final pose). Two protocols "
        "for the other vehicles: `replay` (the paper's: they replay the log) and `reactive` "
        "(the world's driving rules, reacting to the policy's ego). At fault: collisions the "
        "ego caused (hit a vehicle ahead, a stopped one, or one beside it from outside its "
        "lane), not those where it was hit from behind or while stopped "
        "(`minimanc.metrics`). TTC: share of steps with a time to collision under 1 s. "
        "Along-/cross-track: the mean |displacement| from the human along and across the "
        "human's heading (the ADE split into speed and steering).",
        "",
    ]
    header = "| Model | " + " | ".join(_HEAD) + " |"
    rule = "|---" * (len(_HEAD) + 1) + "|"
    for agents, t1 in protocols(results).items():
        for setting, table in t1.items():
            lines += [f"## Table I — setting `{setting}`, agents `{agents}`", "", header, rule]
            for m, agg in table.items():
                n = 1 if m in REFERENCE_ROWS else ns
                lines.append(f"| {lab(m)} | " + " | ".join(cell(agg, k, n) for k in _COLS)
                             + " |")
            lines.append("")
            lines += floor_ratios(table, agents, setting, lab)
            lines += contact_table(table, agents, setting, lab)
    fam_header = "| Model | Family | scenes | " + " | ".join(_HEAD) + " |"
    fam_rule = "|---" * (len(_HEAD) + 3) + "|"
    for agents, by_setting in results.get("families", {}).items():
        for setting, table in by_setting.items():
            lines += [f"## Per scenario family — setting `{setting}`, agents `{agents}`", "",
                      "Free road: straight or curved without a cut-in; junction: an "
                      "intersection; cut-in: a scene with a cut-in (on any map).", "",
                      fam_header, fam_rule]
            for m, fams in table.items():
                n = 1 if m in REFERENCE_ROWS else ns
                for fam, agg in fams.items():
                    k = int(agg["n_scenes"]["mean"]) if "n_scenes" in agg else "?"
                    lines.append(f"| {lab(m)} | {_FAMILY_LABELS.get(fam, fam)} | {k} | "
                                 + " | ".join(cell(agg, c_, n) for c_ in _COLS) + " |")
            lines.append("")
    se = results.get("sample_efficiency")
    if se:
        fr = se["fractions"]
        lines += [f"## Sample efficiency — ADE (m), setting `{se['setting']}`"
                  + (f", agents `{se['agents']}`" if "agents" in se else ""), "",
                  "| Model | " + " | ".join(f"{round(100 * f)} %" for f in fr) + " |",
                  "|---" * (len(fr) + 1) + "|"]
        for m, aggs in se["models"].items():
            lines.append(f"| {lab(m)} | " + " | ".join(cell(a, "ade", ns) for a in aggs) + " |")
        lines.append("")
    qs = results.get("q_states")
    if qs:
        lines += ["## MANC: number of q-states"
                  + (f" (agents `{qs['agents']}`)" if "agents" in qs else ""), "",
                  "| #q | " + " | ".join(_HEAD) + " |", rule]
        for n, agg in zip(qs["n_states"], qs["results"]):
            lines.append(f"| {n} | " + " | ".join(cell(agg, k, ns) for k in _COLS) + " |")
        lines.append("")
    ab = results.get("ablation")
    if ab:
        lines += ["## Self-ablation" + (f" (agents `{ab['agents']}`)" if "agents" in ab else ""),
                  "", header, rule]
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
    md = results.get("modes")
    if md and md.get("models"):
        counts = md.get("mode_counts", {})
        total = sum(counts.values()) or 1
        lines += ["## Are vAGN's q-states driving modes?", "",
                  "Open loop on the validation scenes (the model sees the human's "
                  "observations; q starts uniform): the mutual information between q's most "
                  "likely state and the human's mode at each step, against a shuffled-scene "
                  "baseline (each scene's q paired with another scene's modes; "
                  "`minimanc.metrics.modes.mode_information`). Human modes: "
                  + ", ".join(f"{k} {100 * v / total:.0f} %" for k, v in counts.items())
                  + ".", "",
                  "| Model | MI (bits) | shuffled (bits) | shuffled 95 % | H(mode) (bits) | "
                  "states used | q change / step | argmax switches |",
                  "|---" * 8 + "|"]
        for m, agg in md["models"].items():
            lines.append(
                f"| {lab(m)} | " + " | ".join(
                    cell(agg, k, ns) for k in ("mi_bits", "shuffled_mi_bits", "shuffled_mi_p95",
                                               "mode_entropy_bits", "states_used", "q_change"))
                + f" | {cell(_percent(agg, 'switch_rate'), 'switch_rate', ns)} % |")
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
    if results.get("dagger"):
        lines += dagger_markdown(results["dagger"], ns, lab)
    lines += ["## The paper's claims, checked", ""]
    if ns == 1:
        lines += ["With one seed the seed-to-seed spread is unknown: small differences below "
                  "may be noise (`minimanc reproduce --seeds 3`).", ""]
    for f in results.get("findings", []):
        mark = {True: "holds", False: "does NOT hold", None: "not tested"}[f["holds"]]
        lines.append(f"- **{f['claim']}** — {mark}. {f['detail']}.")
    lines.append("")
    if results.get("provenance"):
        lines.append(provenance_markdown(results["provenance"], results.get("wall_time_s")))
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
