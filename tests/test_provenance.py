"""The README's results section: every number is quoted from a committed results file."""

from __future__ import annotations

from pathlib import Path

import pytest

from minimanc import cli
from minimanc.studies import provenance

ROOT = Path(__file__).resolve().parent.parent

TABLE = """# Closed-loop results

Intro 1.25 text.

## Table I — setting `paper`

| Model | ADE (m) |
|---|---|
| MANC | 15.60 ± 3.10 |

## Provenance

- date: 2026-12-01
"""


def _readme(tmp_path: Path, body: str, table: str = TABLE) -> Path:
    (tmp_path / "results" / "full").mkdir(parents=True)
    (tmp_path / "results" / "full" / "table1.md").write_text(table)
    readme = tmp_path / "README.md"
    readme.write_text(body)
    return readme


QUOTED = """# x

## What `minimanc reproduce` measured
Table I of the full preset:

<!-- quote: results/full/table1.md#Table I — setting `paper` -->
| Model | ADE (m) |
|---|---|
| MANC | 15.60 ± 3.10 |
<!-- end quote -->

## Other
Version 3.11 is fine here.
"""


@pytest.mark.parametrize("readme", ["README.md", "research/why_it_crashes/REPORT.md",
                                    "research/dagger_study/REPORT.md",
                                    "research/seeing_the_leader/README.md"])
def test_the_committed_reports_quote_their_results_files_exactly(readme):
    problems = provenance.check_readme(ROOT / readme)
    assert problems == [], "\n".join(problems)


def test_a_matching_quote_passes(tmp_path):
    assert provenance.check_readme(_readme(tmp_path, QUOTED)) == []


def test_an_edited_number_in_a_quote_is_found(tmp_path):
    readme = _readme(tmp_path, QUOTED.replace("15.60 ± 3.10", "15.50 ± 3.10"))
    (p,) = provenance.check_readme(readme)
    assert "line 6" in p and "differs" in p


def test_a_number_typed_outside_a_quote_is_found(tmp_path):
    readme = _readme(tmp_path, QUOTED.replace("Table I of the full preset:",
                                              "MANC: 10.2 m, collides in 30 % of scenes:"))
    problems = provenance.check_readme(readme)
    assert len(problems) == 2
    assert "'10.2'" in problems[0] and "'30 %'" in problems[1]


def test_numbers_outside_the_results_section_and_plain_integers_are_not_checked(tmp_path):
    readme = _readme(tmp_path, QUOTED.replace("Table I of the full preset:",
                                              "Table I of the full preset, 3 seeds, 48 scenes:"))
    assert provenance.check_readme(readme) == []


def test_a_missing_file_or_heading_is_reported(tmp_path):
    readme = _readme(tmp_path, QUOTED.replace("setting `paper` -->", "setting `parity` -->"))
    (p,) = provenance.check_readme(readme)
    assert "found 0 times" in p
    readme.write_text(QUOTED.replace("results/full/", "results/nope/"))
    (p,) = provenance.check_readme(readme)
    assert "does not exist" in p


def test_update_rewrites_the_blocks_from_their_files(tmp_path):
    readme = _readme(tmp_path, QUOTED, TABLE.replace("15.60", "14.00"))
    assert provenance.check_readme(readme) != []
    assert provenance.update_readme(readme) is True
    assert provenance.check_readme(readme) == []
    assert "14.00 ± 3.10" in readme.read_text()
    assert provenance.update_readme(readme) is False


def test_an_unclosed_block_is_an_error(tmp_path):
    readme = _readme(tmp_path, QUOTED.replace("<!-- end quote -->", ""))
    with pytest.raises(ValueError, match="without"):
        provenance.check_readme(readme)


def test_section_stops_at_the_next_heading_of_its_level():
    assert provenance.section(TABLE, "Table I — setting `paper`").splitlines()[-1] == \
        "| MANC | 15.60 ± 3.10 |"
    with pytest.raises(KeyError):
        provenance.section(TABLE + "\n## Provenance\n", "Provenance")


def test_provenance_names_the_command_versions_and_machine():
    p = provenance.provenance(["minimanc", "reproduce", "--quick"])
    assert p["command"] == "minimanc reproduce --quick"
    assert "numpy" in p["packages"] and "minimanc" in p["packages"]
    assert p["cpus"] >= 1 and p["date"].endswith("+00:00")
    md = provenance.provenance_markdown(p, wall_time_s=90.0)
    assert md.startswith("## Provenance") and "wall time: 1.5 min" in md


def test_cli_exit_codes(tmp_path, capsys):
    readme = _readme(tmp_path, QUOTED)
    assert cli.main(["results", "check", str(readme)]) == 0
    readme.write_text(QUOTED.replace("15.60", "15.70"))
    assert cli.main(["results", "check", str(readme)]) == 1
    assert "differs" in capsys.readouterr().err
    assert cli.main(["results", "update", str(readme)]) == 0
    assert "15.60" in readme.read_text()
    assert cli.main(["results", "check", str(tmp_path / "missing.md")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "missing.md" in err[0] and "Traceback" not in err[0]


def test_publish_prints_and_writes_text_with_provenance(tmp_path, capsys):
    assert provenance.publish("# Title\n\nbody\n", None, 1.0) is None
    assert capsys.readouterr().out == "# Title\n\nbody\n"
    assert list(tmp_path.iterdir()) == []
    out = provenance.publish("# Title\n\nbody\n", tmp_path / "sub" / "r.md", 90.0)
    text = out.read_text()
    assert text.startswith("# Title\n\nbody\n## Provenance\n")
    assert "- wall time: 1.5 min" in text
    assert [p.name for p in out.parent.iterdir()] == ["r.md"], "no temporary file left"
