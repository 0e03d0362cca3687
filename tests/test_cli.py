"""Chapter 0 — the ``minimanc`` command as a package: one module per command group, choices
from the library's registries, one set of argument validators (minimanc.cli.common)."""

from __future__ import annotations

import importlib
import math
import re
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from minimanc import cli, inputs
from minimanc.chapters import CHAPTERS, markdown_table
from minimanc.checks import check_int, check_positive
from minimanc.cli import common
from minimanc.cli import info as cli_info
from minimanc.engine import ENGINES
from minimanc.errors import UsageError

ROOT = Path(__file__).resolve().parent.parent

ENGINE_COMMANDS = [
    ["reproduce"],
    ["highway", "train", "--data", "x.npz"],
    ["highway", "eval"],
    ["highway", "render"],
]


@pytest.mark.parametrize("argv", ENGINE_COMMANDS)
def test_engine_choices_are_the_engine_registry(argv, capsys):
    parser = cli.build_parser()
    for name in ENGINES:
        assert parser.parse_args([*argv, "--engine", name]).engine == name
    with pytest.raises(SystemExit) as exc:
        parser.parse_args([*argv, "--engine", "torch"])
    assert exc.value.code == 2 and "invalid choice: 'torch'" in capsys.readouterr().err


def test_setting_choices_are_the_settings_registry():
    parser = cli.build_parser()
    for setting in inputs.SETTINGS:
        args = parser.parse_args(["highway", "train", "--data", "x.npz", "--setting", setting])
        assert args.setting == setting


def test_the_commands_do_not_retype_the_engine_names():
    pattern = re.compile(r"""["']jax["']\s*,\s*["']numpy["']|["']numpy["']\s*,\s*["']jax["']""")
    commands = [p for p in sorted((ROOT / "minimanc").rglob("*.py"))
                if "add_argument(" in p.read_text()]
    assert len(commands) >= 4
    typed = [str(p.relative_to(ROOT)) for p in commands if pattern.search(p.read_text())]
    assert not typed, f"engine names retyped instead of minimanc.engine.ENGINES: {typed}"


def test_every_command_lives_in_the_cli_package():
    parser = cli.build_parser()
    for argv in (["info"], ["exercises", "build"], ["grade", "nb.ipynb"],
                 ["data", "generate"], ["reproduce"], ["highway", "collect"]):
        func = parser.parse_args(argv).func
        assert func.__module__.startswith("minimanc.cli."), (argv, func.__module__)
    for old in ("minimanc.highway_cli", "minimanc.world.cli", "minimanc.studies.cli"):
        with pytest.raises(ModuleNotFoundError):
            __import__(old)


def test_a_command_whose_chapter_is_missing_is_left_out(monkeypatch, capsys):
    monkeypatch.setitem(cli.PLUGINS, "minimanc.cli.data", "minimanc.no_such_chapter")
    parser = cli.build_parser()
    assert parser.parse_args(["reproduce"]).command == "reproduce"
    with pytest.raises(SystemExit):
        parser.parse_args(["data", "generate"])
    assert "invalid choice: 'data'" in capsys.readouterr().err


def test_the_command_package_keeps_no_chapter_map_of_its_own():
    assert not hasattr(cli, "CHAPTERS") and cli_info.CHAPTERS is CHAPTERS


@pytest.mark.parametrize("argv,expected", [
    (["exercises", "run", "missing.ipynb", "--timeout", "0"],
     "minimanc exercises: error: --timeout must be an integer >= 1, got --timeout=0"),
    (["grade", "missing.ipynb", "--timeout", "-1"],
     "minimanc grade: error: --timeout must be an integer >= 1, got --timeout=-1"),
])
def test_timeouts_are_checked_with_the_shared_validator(argv, expected, capsys):
    assert cli.main(argv) == 2
    assert capsys.readouterr().err.strip() == expected


def test_python_dash_m_runs_the_command():
    out = subprocess.run([sys.executable, "-m", "minimanc", "data", "generate", "--scenes",
                          "-3"], capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert out.returncode == 2
    assert out.stderr.strip() == ("minimanc data: error: --scenes must be an integer >= 1, "
                                  "got --scenes=-3")


# --------------------------------------------------------------------------- validators


@given(st.integers(min_value=-5, max_value=5), st.integers(min_value=-50, max_value=50))
def test_check_option_int_accepts_exactly_the_integers_from_the_minimum(minimum, value):
    if value >= minimum:
        assert common.check_option(check_int, "--n", value, minimum) == value
    else:
        with pytest.raises(UsageError, match=rf"^--n must be an integer >= {minimum}, got --n="):
            common.check_option(check_int, "--n", value, minimum)


@pytest.mark.parametrize("value", [True, 2.0, "3", None])
def test_check_option_int_refuses_what_is_not_an_int(value):
    with pytest.raises(UsageError, match="--n must be an integer >= 0"):
        common.check_option(check_int, "--n", value, 0)


@given(st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-10, 10),
                 st.none(), st.text(max_size=3)))
def test_check_option_positive_accepts_exactly_the_positive_finite_numbers(value):
    good = isinstance(value, int | float) and math.isfinite(value) and value > 0
    if good:
        assert common.check_option(check_positive, "--lr", value) == value
    else:  # the library's message (minimanc.checks), raised as the command line's error
        with pytest.raises(UsageError, match=r"^--lr must be (> 0|finite|a real number)"):
            common.check_option(check_positive, "--lr", value)


def test_check_choices_names_the_unknown_and_the_choices():
    assert common.check_choices(["a"], "--models", ("a", "b")) == ["a"]
    with pytest.raises(UsageError, match=r"^--models: unknown model\(s\) c, d; choose from a, b$"):
        common.check_choices(["a", "c", "d"], "--models", ("a", "b"), what="model(s)")


def test_reproduce_sets_the_training_window_of_the_dmp_models(monkeypatch, tmp_path, capsys):
    from minimanc.cli import reproduce as cmd

    seen = {}

    def fake(config, out, **kwargs):
        seen["config"] = config
        raise SystemExit(0)

    monkeypatch.setattr(cmd, "reproduce", fake)
    with pytest.raises(SystemExit):
        cli.main(["reproduce", "--preset", "tiny", "--out", str(tmp_path / "o"),
                  "--dmp-seq-len", "8", "--epochs", "2"])
    assert seen["config"].training.dmp_seq_len == 8 and seen["config"].training.epochs == 2
    for argv, option in ((["--dmp-seq-len", "0"], "--dmp-seq-len"), (["--epochs", "-1"],
                                                                      "--epochs")):
        code = cli.main(["reproduce", "--preset", "tiny", "--out", str(tmp_path / "p"), *argv])
        err = capsys.readouterr().err
        assert code == 2 and f"{option} must be an integer >= 1" in err, err
        assert len(err.strip().splitlines()) == 1


def test_reproduce_passes_the_protocols_of_the_ados(monkeypatch, tmp_path):
    from minimanc.cli import reproduce as cmd

    seen = []

    def fake(config, out, **kwargs):
        seen.append(kwargs["agents"])
        raise SystemExit(0)

    monkeypatch.setattr(cmd, "reproduce", fake)
    for argv in ([], ["--agents", "both"], ["--agents", "replay"], ["--agents", "reactive"]):
        with pytest.raises(SystemExit):
            cli.main(["reproduce", "--preset", "tiny", "--out", str(tmp_path / "o"), *argv])
    assert seen == [("replay", "reactive"), ("replay", "reactive"), ("replay",), ("reactive",)]


def test_reproduce_passes_the_executor_and_refuses_an_address_without_ray(monkeypatch, tmp_path,
                                                                          capsys):
    from minimanc.cli import reproduce as cmd

    seen = []

    def fake(config, out, **kwargs):
        seen.append((kwargs["executor"], kwargs["ray_address"]))
        raise SystemExit(0)

    monkeypatch.setattr(cmd, "reproduce", fake)
    for argv in ([], ["--executor", "ray"], ["--executor", "ray", "--ray-address", "auto"]):
        with pytest.raises(SystemExit):
            cli.main(["reproduce", "--preset", "tiny", "--out", str(tmp_path / "o"), *argv])
    assert seen == [("local", None), ("ray", None), ("ray", "auto")]
    code = cli.main(["reproduce", "--preset", "tiny", "--out", str(tmp_path / "o"),
                     "--ray-address", "auto"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "--ray-address is for --executor ray" in err[0]


def _info_output(capsys, argv=("info",)) -> str:
    assert cli.main(list(argv)) == 0
    return capsys.readouterr().out


def test_info_prints_the_chapter_map_of_minimanc_chapters(capsys):
    out = _info_output(capsys)
    for chapter in CHAPTERS:
        assert f"  {chapter.code} {chapter.name} " in out, chapter.notebook
        assert chapter.title in out and all(m in out for m in chapter.modules)
        assert f"exercises: {chapter.exercises}\n" in out
    assert "00_warmup" not in out


@pytest.mark.parametrize("module,label,extra", [
    ("jupyterlab", "JupyterLab", "lab"),
    ("nbval", "nbval", "test"),
    ("highway_env", "highway-env", "highway"),
    ("nbclient", "notebook runner", None),
])
def test_info_reports_a_missing_piece_with_the_line_that_installs_it(
        monkeypatch, capsys, module, label, extra):
    real = importlib.import_module

    def without(name, *args, **kwargs):
        if name == module:
            raise ModuleNotFoundError(f"No module named '{name}'")
        return real(name, *args, **kwargs)

    monkeypatch.setattr(cli_info.importlib, "import_module", without)
    out = _info_output(capsys)
    hint = f"pip install -e '.[{extra}]'" if extra else "pip install -e ."
    [row] = [line for line in out.splitlines()
             if line[:10] in ("  ok      ", "  MISSING ") and line[10:].startswith(f"{label} ")]
    assert row.startswith("  MISSING") and row.endswith(f"install: {hint}"), row
    last = out.rstrip().splitlines()[-1]
    assert last.startswith("Some pieces are missing; to install them: pip install -e "), last
    assert extra is None or extra in last.split("[")[1], last


def test_info_says_when_a_command_of_the_readme_is_not_on_path(monkeypatch, capsys):
    monkeypatch.setattr(cli_info.shutil, "which", lambda name: None)
    out = _info_output(capsys)
    assert ("absent  jupyter          not on PATH: activate the environment "
            "(source .venv/bin/activate) or run `python -m jupyterlab`") in out


def test_install_line_names_every_missing_extra_once():
    assert cli_info.install_line({None}) == "pip install -e ."
    assert cli_info.install_line({"test", None, "lab"}) == "pip install -e '.[lab,test]'"


def test_info_prints_the_readme_table(capsys):
    assert _info_output(capsys, ("info", "--readme-table")) == markdown_table()
