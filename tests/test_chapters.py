"""The chapter map of :mod:`minimanc.chapters` against the tree, the notebooks and the README.

* every module the map names exists, and every module under ``minimanc/`` is either of a
  chapter, whose docstring opens with "Chapter N — " for the N the map gives it, or one of
  :data:`~minimanc.chapters.SHARED`, whose docstring names no chapter;
* every notebook in ``tutorials/``, ``solutions/`` and ``exercises/`` is a chapter's, every
  chapter has its three, and each notebook's first markdown cell is headed
  "Chapter N — " and names the chapter's modules;
* the README's "## Chapters" table is :func:`~minimanc.chapters.markdown_table`.

Docstrings are read from the source files (``ast``), so the check needs no optional
dependency of the modules it reads.
"""

from __future__ import annotations

import ast
import json
import re
from pathlib import Path

import pytest

from minimanc.chapters import CHAPTERS, SHARED, chapter_of, markdown_table

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "minimanc"
FOLDERS = ("tutorials", "solutions", "exercises")
_CHAPTER_LINE = re.compile(r"Chapter (\d+)(?: [^—]*)? — ")  # "Chapter 11 in the study — " too


def module_files() -> dict[str, Path]:
    """Dotted name -> source file of every module under ``minimanc/``."""
    found = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = path.relative_to(ROOT).with_suffix("").parts
        if parts[-1] == "__init__":
            parts = parts[:-1]
        found[".".join(parts)] = path
    return found


MODULES = module_files()


def docstring(path: Path) -> str:
    return ast.get_docstring(ast.parse(path.read_text(encoding="utf-8"))) or ""


def first_markdown(path: Path) -> str:
    cells = json.loads(path.read_text(encoding="utf-8"))["cells"]
    return next("".join(c["source"]) for c in cells if c["cell_type"] == "markdown")


def test_the_map_is_in_order_and_names_each_module_once():
    assert [c.number for c in CHAPTERS] == list(range(len(CHAPTERS)))
    assert all(c.notebook.startswith(c.code + "_") for c in CHAPTERS)
    named = [m for c in CHAPTERS for m in c.modules + c.also] + list(SHARED)
    assert len(named) == len(set(named)), sorted(m for m in named if named.count(m) > 1)


@pytest.mark.parametrize("module", sorted({m for c in CHAPTERS for m in c.modules + c.also}
                                          | set(SHARED)))
def test_every_module_the_map_names_exists(module):
    assert module in MODULES, f"minimanc.chapters names {module}, which has no source file"


@pytest.mark.parametrize("module", sorted(MODULES))
def test_each_module_docstring_names_the_chapter_the_map_gives_it(module):
    doc = docstring(MODULES[module])
    first = doc.splitlines()[0] if doc else ""
    chapter = chapter_of(module)
    if module in SHARED:
        assert chapter is None and not first.startswith("Chapter"), (
            f"{module} is shared (minimanc.chapters.SHARED) but its docstring says: {first}")
        return
    assert chapter is not None, f"{module} is of no chapter: add it to minimanc.chapters"
    match = _CHAPTER_LINE.match(first)
    assert match, f"{module}'s docstring must open with 'Chapter {chapter.number} — ': {first}"
    assert int(match.group(1)) == chapter.number, (
        f"{module}: its docstring says chapter {match.group(1)}, minimanc.chapters says "
        f"chapter {chapter.number} ({chapter.notebook})")


def test_chapter_of_takes_the_longest_owner():
    assert chapter_of("minimanc.world.raster").number == 7
    assert chapter_of("minimanc.dagger.expert").number == 11
    assert chapter_of("minimanc.autodiff.nn").number == 2
    assert chapter_of("minimanc.autodiff.nnx").number == 1
    assert chapter_of("minimanc.worlds") is None
    assert chapter_of("minimanc.checks") is None


def test_every_notebook_is_a_chapter_of_the_map_and_every_chapter_has_its_three():
    names = {c.notebook for c in CHAPTERS}
    for folder in FOLDERS:
        present = {p.stem for p in (ROOT / folder).glob("*.ipynb")}
        assert present <= names, f"{folder}/ holds notebooks of no chapter: {present - names}"
        assert names <= present, f"{folder}/ lacks the notebooks of {names - present}"


@pytest.mark.parametrize("folder", FOLDERS)
@pytest.mark.parametrize("chapter", CHAPTERS, ids=lambda c: c.notebook)
def test_each_notebook_first_cell_names_its_chapter_and_modules(folder, chapter):
    text = first_markdown(ROOT / folder / f"{chapter.notebook}.ipynb")
    heading = text.lstrip().splitlines()[0]
    assert heading.startswith(f"# Chapter {chapter.number} — "), heading
    missing = [m for m in chapter.modules if f"`{m}`" not in text]
    assert not missing, f"{folder}/{chapter.notebook}: the first cell does not name {missing}"


def test_the_readme_chapter_table_is_the_map():
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    assert "\n## Chapters\n" in readme, "README.md has no '## Chapters' section"
    table = readme.split("\n## Chapters\n", 1)[1].split("\n\n", 1)[0] + "\n"
    assert table == markdown_table(), (
        "README.md's '## Chapters' table differs from minimanc.chapters: "
        "paste the output of `minimanc info --readme-table`")
