"""Chapter 9 — :func:`reproduce`: every study of a configuration, written to ``table1.md``,
``results.json`` and ``figures/`` (the ``minimanc reproduce`` command is
:mod:`minimanc.cli.reproduce`)."""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from pathlib import Path

from minimanc.studies.config import StudyConfig
from minimanc.studies.dagger_study import dagger_figures, run_dagger
from minimanc.studies.figures import write_figures
from minimanc.studies.provenance import provenance, write_json, write_text
from minimanc.studies.recorded import data_notes, is_recorded
from minimanc.studies.report import json_safe, table_markdown
from minimanc.studies.runner import Study

__all__ = ["reproduce", "with_data_notes"]


def with_data_notes(markdown: str, config: StudyConfig) -> str:
    """``markdown`` (:func:`~minimanc.studies.report.table_markdown`) with the lines about
    ``config``'s data file (:func:`~minimanc.studies.recorded.data_notes`) after the
    introduction, before the first section."""
    notes = data_notes(config)
    if not notes:
        return markdown
    head, sep, rest = markdown.partition("\n## ")
    return head.rstrip("\n") + "\n\n" + "\n".join(notes) + sep + rest


def reproduce(config: StudyConfig, out: str | Path, engine: str = "jax", workers: int | None = None,
              progress: bool = True, figures: bool = True,
              log: Callable[[str], None] | None = None,
              agents: Sequence[str] = ("replay", "reactive"),
              command: Sequence[str] | None = None, executor: str = "local",
              ray_address: str | None = None, dagger: bool = False) -> dict:
    """Run every study of ``config`` and write ``table1.md``, ``results.json`` and
    ``figures/`` under ``out``; Table I under each protocol of ``agents``
    (:class:`~minimanc.studies.runner.Study`). Returns the results dict (also with
    ``"files"``, the run's ``"provenance"`` (:func:`minimanc.studies.provenance.provenance` of
    ``command``, the command line; default ``sys.argv``) and
    ``"wall_time_s"``, which ``table1.md`` ends with). ``executor`` ("local" or "ray") and
    ``ray_address`` choose where the trainings run (:mod:`minimanc.studies.executors`);
    ``dagger`` adds behaviour cloning against DAgger for MANC and the CNN
    (:mod:`minimanc.studies.dagger_study`, ``results["dagger"]``).

    On a given dataset file (``config`` from :func:`minimanc.studies.recorded.data_config`)
    ``table1.md`` says so after its introduction; on recorded data ``agents`` must be
    ``("replay",)``, ``dagger`` is refused and Table I has no bound rows (why:
    :mod:`minimanc.studies.recorded`)."""
    if dagger and is_recorded(config):
        raise ValueError("dagger needs the world's expert in states the log never visited; "
                         "recorded data has none (behaviour cloning against DAgger runs on "
                         "generated data only)")
    started = time.perf_counter()
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    study = Study(config, out, engine=engine, workers=workers, progress=progress, log=log,
                  agents=agents, executor=executor, ray_address=ray_address)
    try:
        results = study.run()
        if dagger:
            t0 = time.perf_counter()
            results["dagger"] = run_dagger(study)
            results["timing_s"]["dagger"] = round(time.perf_counter() - t0, 1)
        files = {"table1": str(out / "table1.md"), "results": str(out / "results.json")}
        if figures:
            t0 = time.perf_counter()
            paths = write_figures(study, results, out / "figures")
            study.timing["figures"] = time.perf_counter() - t0
            results["timing_s"]["figures"] = round(study.timing["figures"], 1)
            if dagger:
                paths += dagger_figures(results["dagger"], out / "figures")
            files["figures"] = [str(p) for p in paths]
    finally:
        study.close()
    results["files"] = files
    results["provenance"] = provenance(command)
    results["wall_time_s"] = round(time.perf_counter() - started, 1)
    write_text(out / "table1.md", with_data_notes(table_markdown(results), config))
    write_json(out / "results.json", json_safe(results))
    return results

