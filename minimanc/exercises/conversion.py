"""Chapter 0 — percent-format sources → notebooks, and executing a notebook in place.

:func:`cells_from_percent` parses the ``# %%`` cell headers described in
CONTRIBUTING.md, :func:`convert` writes (and executes) the notebook, :func:`run`
executes one in place and stops at an unexpected error.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import nbformat

from minimanc.exercises.markers import (
    META_KEY,
    RAISES_TAG,
    NotebookFormatError,
    is_grade_cell,
    is_solution_cell,
    validate,
)

__all__ = [
    "KERNEL_ARGS",
    "TIMEOUT_ENAME",
    "cells_from_percent",
    "convert",
    "notebook_client",
    "run",
]

TIMEOUT_ENAME = "GradingTimeout"
KERNEL_ARGS = ["--IPKernelApp.log_level=ERROR"]
"""Kernel flags: keep the kernel's own start-up warnings (e.g. about its TCP
transport) out of what the student sees."""


# ---------------------------------------------------------------------------- convert
_HEADER = re.compile(r"^# %%(.*)$")
_ATTR = re.compile(r"""(\w+)=("[^"]*"|'[^']*'|\[[^\]]*\]|\S+)""")


_NOQA = re.compile(r"\s+#\s*noqa\b.*$")


def _parse_header(text: str, where: str) -> tuple[str, dict]:
    text = _NOQA.sub("", text.strip())  # a long header may end in a ruff noqa comment
    kind = "code"
    if text.startswith("[markdown]"):
        kind, text = "markdown", text[len("[markdown]"):].strip()
    attrs: dict = {}
    if text.split(" ")[0] in ("solution", "grade"):
        attrs["role"], _, text = text.partition(" ")
    rest = _ATTR.sub("", text).strip()
    if rest:
        raise NotebookFormatError(f"{where}: cannot read cell header attribute {rest!r}")
    for key, value in _ATTR.findall(text):
        try:
            as_json = key in ("tags", "points") or (key == "forbids" and value.startswith("["))
            attrs[key] = json.loads(value) if as_json else value.strip("\"'")
        except json.JSONDecodeError as exc:
            raise NotebookFormatError(f"{where}: {key}={value} is not valid JSON") from exc
    return kind, attrs


def _markdown(lines: list[str]) -> str:
    out = []
    for line in lines:
        if line.startswith("# "):
            out.append(line[2:])
        elif line.strip() == "#":
            out.append("")
        else:
            out.append(line)
    return "\n".join(out).strip("\n")


def cells_from_percent(text: str, name: str = "<source>") -> list:
    """Parse a percent-format script into notebook cells (see CONTRIBUTING.md)."""
    chunks: list[tuple[str, dict, list[str]]] = []
    for number, line in enumerate(text.split("\n"), start=1):
        match = _HEADER.match(line)
        if match:
            kind, attrs = _parse_header(match.group(1), f"{name}: line {number}")
            chunks.append((kind, attrs, []))
        elif chunks:
            chunks[-1][2].append(line)
        elif line.strip():
            raise NotebookFormatError(f"{name}: line {number}: text before the first '# %%'")
    cells = []
    for number, (kind, attrs, lines) in enumerate(chunks):
        if kind == "markdown":
            cells.append(nbformat.v4.new_markdown_cell(_markdown(lines), id=f"c{number:03d}"))
            continue
        cell = nbformat.v4.new_code_cell("\n".join(lines).strip("\n"), id=f"c{number:03d}")
        if attrs.get("tags"):
            cell.metadata["tags"] = list(attrs["tags"])
        role = attrs.get("role")
        if role == "solution":
            cell.metadata["nbgrader"] = {
                "solution": True, "grade": False, "locked": False,
                "grade_id": attrs.get("id", ""), "schema_version": 3,
            }
            cell.metadata[META_KEY] = {"title": attrs.get("title", "")}
            forbids = attrs.get("forbids")
            if forbids:
                if isinstance(forbids, str):
                    forbids = [f for f in re.split(r"[,\s]+", forbids) if f]
                cell.metadata[META_KEY]["forbids"] = list(forbids)
        elif role == "grade":
            cell.metadata["nbgrader"] = {
                "solution": False, "grade": True, "locked": True,
                "grade_id": attrs.get("id", ""), "points": attrs.get("points", 1),
                "schema_version": 3,
            }
        cells.append(cell)
    return cells


def convert(source: Path, target: Path, execute: bool = True, timeout: int = 600):
    """Write the notebook for a percent-format script (and execute it in place)."""
    source, target = Path(source), Path(target)
    nb = nbformat.v4.new_notebook()
    nb.metadata["kernelspec"] = {
        "name": "python3", "display_name": "Python 3", "language": "python"
    }
    nb.metadata["language_info"] = {"name": "python"}
    nb.cells = cells_from_percent(source.read_text(), source.name)
    if any(is_grade_cell(c) or is_solution_cell(c) for c in nb.cells):
        nb.metadata[META_KEY] = {"assignment": target.stem}
        validate(nb, target.name)
    target.parent.mkdir(parents=True, exist_ok=True)
    nbformat.write(nb, target)
    if execute:
        run(target, timeout=timeout)
    return nb


# ------------------------------------------------------------------------ execution
def notebook_client(nb, folder: Path, timeout: int, allow_errors: bool):
    """An nbclient ``NotebookClient`` running ``nb`` in ``folder`` with the kernel flags."""
    from nbclient import NotebookClient  # Jupyter only when a notebook is executed

    return NotebookClient(
        nb,
        timeout=timeout,
        kernel_name="python3",
        allow_errors=allow_errors,
        interrupt_on_timeout=True,
        error_on_timeout={"ename": TIMEOUT_ENAME, "evalue": f"timeout after {timeout} s"},
        extra_arguments=list(KERNEL_ARGS),
        resources={"metadata": {"path": str(folder)}},
    )


def _normalise(nb) -> None:
    """Drop volatile metadata so that committed notebooks diff cleanly."""
    for cell in nb.cells:
        cell.metadata.pop("execution", None)
    nb.metadata.pop("widgets", None)


def run(path: Path, timeout: int = 600) -> None:
    """Execute a notebook in place, stopping at an unexpected error.

    Cells tagged ``raises-exception`` may raise; any other error is re-raised
    with the notebook name and cell index.
    """
    path = Path(path)
    nb = nbformat.read(path, as_version=4)
    client = notebook_client(nb, path.resolve().parent, timeout, allow_errors=True)
    client.execute()
    for index, cell in enumerate(nb.cells):
        if cell.cell_type != "code" or RAISES_TAG in cell.metadata.get("tags", []):
            continue
        for output in cell.get("outputs", []):
            if output.get("output_type") == "error":
                raise RuntimeError(
                    f"{path.name}: cell {index} raised {output.get('ename')}: "
                    f"{output.get('evalue')}"
                )
    _normalise(nb)
    nbformat.write(nb, path)
