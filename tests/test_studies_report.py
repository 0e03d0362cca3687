"""Tests for minimanc.studies.report: the findings decided by the numbers and the markdown
table of a study's results."""

from __future__ import annotations

from minimanc import metrics, studies


def agg(**means):
    """An aggregate with the given means (std 0.1, 3 seeds)."""
    return {k: {"mean": v, "std": 0.1, "n": 3, "values": [v] * 3} for k, v in means.items()}


def row(ce, acc, ade, goal):
    return agg(close_encounters=ce, max_acceleration=acc, ade=ade, goal_distance=goal,
               collision_rate=0.0, off_road_rate=0.0)


def tables(manc_ade, prior=True):
    human = row(2.0, 3.0, 0.0, 0.0)
    fixed = {"human": human, **({"dmp_prior": row(3.0, 2.0, 2.5, 6.0)} if prior else {})}
    return {
        "paper": {**fixed, "cnn": row(1.0, 5.0, 4.0, 9.0),
                  "cnn_lstm": row(5.0, 6.0, 3.0, 8.0), "rvs_g": row(9.0, 1.0, 2.0, 7.0),
                  "manc": row(2.5, 3.2, manc_ade, 3.0)},
        "parity": {**fixed, "cnn": row(1.0, 5.0, 1.5, 4.0),
                   "cnn_lstm": row(5.0, 6.0, 2.5, 5.0), "rvs_g": row(9.0, 1.0, 2.5, 6.0),
                   "manc": row(2.5, 3.2, manc_ade, 3.0)},
    }


def fake_results(manc_ade=1.0, q_ades=(3.0, 2.0, 1.5, 1.0), reactive_manc_ade=None):
    table = {"replay": tables(manc_ade),
             "reactive": tables(manc_ade if reactive_manc_ade is None else reactive_manc_ade)}
    return {
        "config": {**studies.with_form(studies.PRESETS["quick"], "paper").__dict__,
                   "lrs": [1e-3, 3e-3], "n_seeds": 3},
        "engine": "jax",
        "close_gap_m": metrics.CLOSE_GAP,
        "table1": table,
        "sample_efficiency": {"setting": "paper", "fractions": [0.25, 1.0],
                              "models": {"cnn": [row(1, 1, 6.0, 1), row(1, 1, 4.0, 1)],
                                         "manc": [row(1, 1, 2.0, 1), row(1, 1, 1.0, 1)]}},
        "q_states": {"setting": "paper", "n_states": [3, 6, 9, 12],
                     "results": [row(1, 1, a, 1) for a in q_ades]},
        "ablation": {"setting": "paper", "models": {
            "manc": row(2.5, 3.2, manc_ade, 3.0), "vagn_only": row(1.0, 2.0, 5.0, 9.0),
            "dmp_only": row(4.0, 5.0, 1.2, 3.5)}},
        "param_counts": {"paper": {"cnn": 100_000, "cnn_lstm": 120_000, "rvs_g": 200_000,
                                   "manc": 20_000, "vagn_only": 25_000, "dmp_only": 19_000}},
        "lr": {"manc-paper": 1e-3},
    }


def by_id(found):
    return {f["id"]: f for f in found}


def test_findings_follow_the_numbers():
    f = by_id(studies.findings(fake_results()))
    for agents in ("replay", "reactive"):
        assert f[f"manc_best_ade_paper_{agents}"]["holds"] is True
        assert f[f"manc_best_goal_distance_paper_{agents}"]["holds"] is True
        assert f[f"manc_best_ade_parity_{agents}"]["holds"] is True
        assert f[f"manc_near_human_close_encounters_paper_{agents}"]["holds"] is True
        assert f[f"manc_near_human_max_acceleration_paper_{agents}"]["holds"] is True
        assert f"{agents} agents" in f[f"manc_best_ade_paper_{agents}"]["claim"]
    assert f["q_states_ade"]["holds"] is True and "monotone" in f["q_states_ade"]["detail"]
    assert f["ablation_dmp_only_aggressive"]["holds"] is True
    assert f["ablation_vagn_only_safer"]["holds"] is True
    assert f["ablation_vagn_only_worse_goal"]["holds"] is True
    assert f["sample_efficiency"]["holds"] is True
    assert f["param_counts"]["holds"] is True
    # parity lowers cnn's ADE but not rvs_g's: the claim does not hold, the text says why
    assert f["parity_helps_baselines_replay"]["holds"] is False
    assert "rvs_g 2.00 → 2.50" in f["parity_helps_baselines_replay"]["detail"]


def test_findings_report_failures_with_numbers():
    f = by_id(studies.findings(fake_results(manc_ade=2.9, q_ades=(1.0, 2.0, 1.5, 3.0))))
    ade = f["manc_best_ade_paper_replay"]
    assert ade["holds"] is False and "manc 2.90" in ade["detail"] and "best is rvs_g" in ade[
        "detail"]
    assert f["q_states_ade"]["holds"] is False
    assert "not monotone" in f["q_states_ade"]["detail"]
    # parity: cnn 1.50 beats manc 2.90
    assert f["manc_best_ade_parity_replay"]["holds"] is False
    assert "best is cnn" in f["manc_best_ade_parity_replay"]["detail"]


def test_findings_compare_manc_with_its_fixed_gain_prior():
    f = by_id(studies.findings(fake_results(manc_ade=1.0)))["learning_beats_prior_replay"]
    assert f["holds"] is True and "MANC 1.00" in f["detail"] and "fixed gains 2.50" in f["detail"]
    f = by_id(studies.findings(fake_results(manc_ade=2.9)))["learning_beats_prior_reactive"]
    assert f["holds"] is False
    res = fake_results()
    res["table1"] = {a: tables(1.0, prior=False) for a in ("replay", "reactive")}
    assert not any(k.startswith("learning_beats_prior") for k in by_id(studies.findings(res)))


def test_findings_mention_seed_noise():
    res = fake_results(manc_ade=1.95)  # rvs_g 2.00: difference 0.05 < 0.1 + 0.1
    d = by_id(studies.findings(res))["manc_best_ade_paper_replay"]["detail"]
    assert "within the seed spread" in d


def test_findings_say_when_a_claim_holds_under_one_protocol_only():
    # MANC best under replay (1.0 < rvs_g 2.0), not under reactive (2.9 > rvs_g 2.0)
    f = by_id(studies.findings(fake_results(manc_ade=1.0, reactive_manc_ade=2.9)))
    rep_, rea = f["manc_best_ade_paper_replay"], f["manc_best_ade_paper_reactive"]
    assert rep_["holds"] is True and rea["holds"] is False
    for x in (rep_, rea):
        assert "holds under replay agents and not under reactive" in x["detail"], x["detail"]
    # a claim that agrees under both protocols gets no such note
    assert "the protocol decides" not in f["manc_best_goal_distance_paper_replay"]["detail"]


def test_findings_on_a_results_file_without_protocols_read_it_as_replay():
    res = fake_results()
    res["table1"] = tables(1.0, prior=False)
    res["references"] = {"dmp_prior": row(3.0, 2.0, 2.5, 6.0)}
    f = by_id(studies.findings(res))
    assert f["manc_best_ade_paper_replay"]["holds"] is True
    assert f["learning_beats_prior_replay"]["holds"] is True
    assert not any(k.endswith("_reactive") for k in f)
    assert "agents `replay`" in studies.table_markdown({**res, "findings": list(f.values())})


def track(along, cross, bias=-1.0):
    return agg(along_track=along, cross_track=cross, along_bias=bias)


def test_findings_tell_where_the_error_comes_from():
    res = fake_results()
    for t in res["table1"]["replay"].values():
        for m in t:
            t[m] = {**t[m], **track(0.0 if m == "human" else 5.0, 1.0)}
    f = by_id(studies.findings(res))
    e = f["error_is_along_track_paper_replay"]
    assert e["holds"] is True and "manc 5.00 / 1.00 (bias -1.00)" in e["detail"]
    assert "error_is_along_track_paper_reactive" not in f  # no split in that table
    res["table1"]["replay"]["paper"]["cnn"].update(track(0.5, 2.0))
    assert by_id(studies.findings(res))["error_is_along_track_paper_replay"]["holds"] is False


def mode_agg(mi, shuffled, p95):
    return agg(mi_bits=mi, shuffled_mi_bits=shuffled, shuffled_mi_p95=p95,
               mode_entropy_bits=1.5, q_change=0.4, switch_rate=0.66, states_used=3,
               excess_bits=mi - shuffled, p_value=0.01)


def test_the_explainability_claim_is_decided_by_the_mode_information():
    res = fake_results()
    res["modes"] = {"setting": "paper", "mode_counts": {"free": 30, "follow": 10},
                    "models": {"manc": mode_agg(0.30, 0.05, 0.10),
                               "vagn_only": mode_agg(0.08, 0.05, 0.07)}}
    f = by_id(studies.findings(res))
    m, v = f["vagn_modes_manc"], f["vagn_modes_vagn_only"]
    assert m["holds"] is True and "carries 0.300 bits" in m["detail"]
    assert "shuffled-scene baseline 0.050" in m["detail"] and "claim holds" in m["detail"]
    # above the 95th percentile but only 0.03 bits above the baseline's mean: not a mode
    assert v["holds"] is False and "does not hold" in v["detail"]
    md = studies.table_markdown({**res, "findings": list(f.values())})
    assert "Are vAGN's q-states driving modes?" in md and "free 75 %" in md
    assert "| MANC | 0.30 ± 0.10 | 0.05 ± 0.10 |" in md and "| 66.00 ± 10.00 % |" in md


def test_reactive_human_with_an_at_fault_collision_is_reported():
    res = fake_results()
    for t in res["table1"]["reactive"].values():
        t["human"] = {**t["human"], **agg(at_fault_collision_rate=0.0, collision_rate=0.0)}
    assert by_id(studies.findings(res))["reactive_human_no_at_fault"]["holds"] is True
    res["table1"]["reactive"]["paper"]["human"].update(agg(at_fault_collision_rate=4.0))
    f = by_id(studies.findings(res))["reactive_human_no_at_fault"]
    assert f["holds"] is False and "4.00 %" in f["detail"]


def test_table_markdown_contains_every_section():
    res = fake_results()
    res["findings"] = studies.findings(res)
    res["families"] = {"replay": {"paper": {"manc": {
        "free": {**row(1.0, 1.0, 4.0, 2.0), "n_scenes": {"mean": 7.0, "std": 0.0}}}}}}
    md = studies.table_markdown(res)
    for text in ("setting `paper`, agents `replay`", "setting `parity`, agents `replay`",
                 "setting `paper`, agents `reactive`", "| MANC | 2.50 ± 0.10",
                 "| Human | 2.00 |", "Sample efficiency", "q-states", "Self-ablation",
                 "Parameters", "holds", "does NOT hold", "| 20,000 |",
                 "| DMP at fixed gains | 3.00 | 2.00 | 2.50 |", "% at fault", "along-track (m)",
                 "cross-track (m)", "% TTC < 1 s", "route progress",
                 "## Per scenario family — setting `paper`, agents `replay`",
                 "| MANC | free road | 7 | 1.00 ± 0.10 |"):
        assert text in md, text


def test_table_markdown_says_which_raster_ran_and_the_perception_weight():
    from dataclasses import asdict, replace

    from minimanc import world

    res = fake_results()
    res["findings"] = studies.findings(res)
    head = studies.table_markdown(res).split("\n## ")[0]
    assert "24 validation scenes, 64×64 RGB raster (the paper's form), 3 epochs, " in head
    assert "λ" not in head
    quick = studies.with_form(studies.PRESETS["quick"], "paper")
    raster = world.RasterConfig.from_extent(60.0, 25.0, 50 / 64, encoding="channels",
                                            route=True, history=2)
    learner = replace(quick, raster=raster,
                      training=replace(quick.training, perception_weight=1.0))
    for config in (learner.__dict__, asdict(learner)):  # the study's object, results.json's dict
        head = studies.table_markdown({**res, "config": {**config, "n_seeds": 3}}).split("\n## ")[0]
        assert ("24 validation scenes, 90×64 binary channels (route, vehicles at t, t−1, t−2), "
                "60 m ahead, 3 epochs with the auxiliary perception loss (λ = 1), learning "
                "rate") in head
