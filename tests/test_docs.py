"""The README and the pages of docs/: no dead link, no stale path or name, generated parts
in sync, and every example that says it runs, run."""

from __future__ import annotations

import importlib
import re
from pathlib import Path

import pytest

from minimanc.studies import presets_table

ROOT = Path(__file__).resolve().parent.parent
PAGES = ["README.md", "docs/instructors.md", "docs/library.md", "docs/reproduce.md"]

LINK = re.compile(r"\[[^\]]*\]\(([^)\s]+)\)")
CODE = re.compile(r"`([^`\n]+)`")
# a path of the repository written in code quotes: a known top folder, then a path
REPO_PATH = re.compile(r"^(?:minimanc|docs|tests|research|benchmarks|notebooks_src|tutorials|"
                       r"solutions|exercises|results|\.ci)/[\w./-]*$")
DOTTED = re.compile(r"^minimanc(?:\.\w+)+$")
# outputs a command writes (they exist after it ran, not in a clone)
WRITTEN = ("minimanc_results/", "data/")


def pages() -> list[Path]:
    return [ROOT / p for p in PAGES if (ROOT / p).exists()]


def test_every_page_exists() -> None:
    missing = [p for p in PAGES if not (ROOT / p).exists()]
    assert not missing, f"missing documentation pages: {missing}"


def test_readme_is_a_front_door() -> None:
    lines = (ROOT / "README.md").read_text(encoding="utf-8").splitlines()
    assert len(lines) <= 250, f"README.md has {len(lines)} lines (at most 250)"
    text = "\n".join(lines)
    for page in PAGES[1:]:
        assert f"]({page})" in text, f"README.md does not link {page}"


@pytest.mark.parametrize("page", PAGES)
def test_links_resolve(page: str) -> None:
    path = ROOT / page
    text = path.read_text(encoding="utf-8")
    dead = []
    for target in LINK.findall(text):
        if target.startswith(("http://", "https://", "mailto:")):
            continue
        file, _, anchor = target.partition("#")
        dest = (path.parent / file).resolve() if file else path
        if not dest.exists():
            dead.append(target)
        elif anchor and dest.suffix == ".md":
            slugs = {heading_slug(h) for h in re.findall(r"^#+ (.+)$", dest.read_text(
                encoding="utf-8"), re.M)}
            if anchor not in slugs:
                dead.append(target)
    assert not dead, f"{page}: dead links {dead}"


def heading_slug(heading: str) -> str:
    """GitHub's anchor of a Markdown heading."""
    s = re.sub(r"[^\w\- ]", "", heading.strip().lower())
    return s.replace(" ", "-")


@pytest.mark.parametrize("page", PAGES)
def test_paths_and_names_exist(page: str) -> None:
    text = (ROOT / page).read_text(encoding="utf-8")
    stale = []
    for code in CODE.findall(text):
        for word in code.split():
            word = word.strip(",;:()")
            if "NN" in word or "<" in word:  # a placeholder, e.g. tutorials/NN_name.ipynb
                continue
            if REPO_PATH.match(word) and not word.startswith(WRITTEN):
                if not (ROOT / word.split("#")[0].split("::")[0]).exists():
                    stale.append(word)
            elif DOTTED.match(word) and not resolves(word):
                stale.append(word)
    assert not stale, f"{page}: paths or names that do not exist: {stale}"


def resolves(dotted: str) -> bool:
    """Whether ``minimanc.a.b.c`` is a module or an attribute of one."""
    parts = dotted.split(".")
    for i in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:i]))
        except ImportError:
            continue
        try:
            for name in parts[i:]:
                obj = getattr(obj, name)
        except AttributeError:
            return False
        return True
    return False


def test_presets_table_is_generated() -> None:
    text = (ROOT / "docs/reproduce.md").read_text(encoding="utf-8")
    assert presets_table() in text, ("docs/reproduce.md's presets table differs from "
                                     "minimanc.studies.presets_table(): paste it again")


def test_the_checks_catch_a_dead_link_and_a_stale_name(tmp_path: Path) -> None:
    assert not resolves("minimanc.world.no_such_thing")
    assert resolves("minimanc.world.generate") and resolves("minimanc.diagnose.bounds")
    assert heading_slug("Reading a result: the bound rows") == "reading-a-result-the-bound-rows"
    assert not REPO_PATH.match("minimanc reproduce") and REPO_PATH.match("research/x/REPORT.md")


def python_blocks(markdown: str, section: str) -> list[str]:
    """The fenced ``python`` blocks of the ``## section`` of a Markdown text."""
    body = markdown.split(f"\n## {section}\n", 1)[1].split("\n## ", 1)[0]
    return re.findall(r"```python\n(.*?)```", body, re.S)


def test_the_readme_s_library_example_runs(capsys: pytest.CaptureFixture[str]) -> None:
    """The README's example generates data, trains MANC, drives it closed loop and prints
    a line of metrics for MANC and for the human's log (whose ADE is 0 by definition)."""
    (block,) = python_blocks((ROOT / "README.md").read_text(encoding="utf-8"),
                             "Reusing the library")
    exec(compile(block, "README.md", "exec"), {"__name__": "readme_example"})
    lines = capsys.readouterr().out.splitlines()
    assert [ln.split()[0] for ln in lines] == ["MANC", "human"]
    assert re.fullmatch(r"human +ADE +0\.00 m  collisions +0%", lines[1]), lines[1]
    ade = float(lines[0].split()[2])
    assert 0.0 < ade < 100.0
