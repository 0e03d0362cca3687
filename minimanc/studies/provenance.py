"""Chapter 9 — where a measured number comes from: provenance, and the README's quotes.

Every number the README's results section shows is *quoted* from a committed file that
the command which measured it wrote (``minimanc reproduce --out results/<preset>`` writes
``table1.md`` and ``results.json``; a benchmark writes its own ``.md``). Such a file
carries its :func:`provenance`: the command line, the date, the package versions and the
machine. In the README a quote is a block ::

    <!-- quote: results/full/table1.md#Table I — setting `paper` -->
    ...the section of that heading, verbatim...
    <!-- end quote -->

:func:`check_readme` lists every block whose text differs from its file, and every
measured-looking number (a decimal, a percentage) written in the results section outside a
block; :func:`update_readme` rewrites the blocks from their files. ``minimanc results
check|update [README.md]`` runs them from the command line (:mod:`minimanc.cli.results`).
"""

from __future__ import annotations

import datetime as _dt
import importlib.metadata
import json
import os
import platform
import re
import shlex
import subprocess
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from minimanc.world.datawriter import temp_file

__all__ = [
    "PACKAGES",
    "RESULTS_HEADING",
    "Quote",
    "check_readme",
    "cpu_model",
    "provenance",
    "provenance_markdown",
    "publish",
    "quotes",
    "section",
    "update_readme",
    "write_text",
]

PACKAGES: tuple[str, ...] = ("minimanc", "jax", "jaxlib", "optax", "numpy", "matplotlib",
                             "highway-env", "gymnasium", "ray")
"""Distributions whose versions a provenance record lists (those installed)."""

RESULTS_HEADING = "## What `minimanc reproduce` measured"
"""The README section whose numbers must all be quoted from results files."""

_BEGIN = re.compile(r"^<!-- quote: (?P<path>[^#\s]+)#(?P<heading>.+?) -->$")
_END = "<!-- end quote -->"
_MEASURED = re.compile(r"(?<![\w.`/-])\d+\.\d+(?![\w`/])|\b\d+(?:\.\d+)?\s?%")


def cpu_model() -> str:
    """The CPU's model name (``/proc/cpuinfo`` on Linux, else :func:`platform.processor`)."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.lower().startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def _git_commit(root: Path) -> str | None:
    try:
        head = subprocess.run(["git", "-C", str(root), "rev-parse", "--short", "HEAD"],
                              capture_output=True, text=True, timeout=10, check=False)
        dirty = subprocess.run(["git", "-C", str(root), "status", "--porcelain",
                                "--untracked-files=no"],
                               capture_output=True, text=True, timeout=10, check=False)
    except (OSError, subprocess.SubprocessError):
        return None
    if head.returncode != 0 or not head.stdout.strip():
        return None
    return head.stdout.strip() + ("+dirty" if dirty.stdout.strip() else "")


def _program(argv0: str) -> str:
    """``minimanc`` for the console script, ``python <path>`` for a script (relative to the
    working directory when inside it)."""
    path = Path(argv0)
    if path.suffix != ".py":
        return path.name
    try:
        path = path.resolve().relative_to(Path.cwd().resolve())
    except ValueError:
        pass
    return f"python {path.as_posix()}"


def provenance(argv: Sequence[str] | None = None) -> dict:
    """Where a result comes from: a JSON-ready dict.

    Parameters
    ----------
    argv : sequence of str, optional
        The command line that produced the result (default: ``sys.argv``, its first item
        shortened to the program's name, or ``python <path>`` for a script).

    Returns
    -------
    dict
        ``command`` (str), ``date`` (UTC, ISO 8601, seconds), ``python``, ``platform``,
        ``cpu``, ``cpus`` (int), ``packages`` ({distribution: version} of the installed
        :data:`PACKAGES`) and ``commit`` (the git commit of the package's checkout, or
        ``None`` outside one; ``+dirty`` when tracked files had uncommitted changes).
    """
    args = [str(a) for a in (sys.argv if argv is None else argv)]
    program = _program(args[0]) if argv is None and args else shlex.join(args[:1])
    command = " ".join([program] + ([shlex.join(args[1:])] if args[1:] else []))
    packages = {}
    for dist in PACKAGES:
        try:
            packages[dist] = importlib.metadata.version(dist)
        except importlib.metadata.PackageNotFoundError:
            continue
    return {
        "command": command,
        "date": _dt.datetime.now(_dt.timezone.utc).replace(microsecond=0).isoformat(),
        "python": platform.python_version(),
        "platform": platform.platform(),
        "cpu": cpu_model(),
        "cpus": os.cpu_count() or 1,
        "packages": packages,
        "commit": _git_commit(Path(__file__).resolve().parent.parent),
    }


def provenance_markdown(prov: dict, wall_time_s: float | None = None) -> str:
    """A ``## Provenance`` section (markdown) for a record of :func:`provenance`."""
    pk = ", ".join(f"{k} {v}" for k, v in sorted(prov.get("packages", {}).items()))
    lines = ["## Provenance", "", f"- command: `{prov.get('command', '?')}`",
             f"- date: {prov.get('date', '?')}",
             f"- machine: {prov.get('cpu', '?')}, {prov.get('cpus', '?')} CPUs, "
             f"{prov.get('platform', '?')}, Python {prov.get('python', '?')}",
             f"- packages: {pk}"]
    if prov.get("commit"):
        lines.append(f"- commit: {prov['commit']}")
    if wall_time_s is not None:
        lines.append(f"- wall time: {wall_time_s / 60:.1f} min")
    return "\n".join(lines) + "\n"


def publish(text: str, out: str | Path | None, wall_time_s: float) -> Path | None:
    """Print a benchmark's markdown ``text`` and, when ``out`` is given, write it there
    atomically (:func:`write_text`) followed by its :func:`provenance_markdown` section."""
    print(text, end="")
    if out is None:
        return None
    return write_text(out, text + provenance_markdown(provenance(), wall_time_s))


def write_text(path: str | Path, text: str) -> Path:
    """Write ``text`` to ``path`` atomically (a temporary file in the same directory, then
    :func:`os.replace`; nothing half-written is left behind on failure)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = temp_file(path)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(text)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    return path


def write_json(path: str | Path, obj: Any) -> Path:
    """Write ``obj`` as JSON (``indent=1``, sorted keys) atomically with :func:`write_text`."""
    return write_text(path, json.dumps(obj, indent=1, sort_keys=True))


def read_json_or_none(path: Path) -> Any:
    """The JSON in ``path``, or ``None`` if it is missing or unreadable (a broken cache entry)."""
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError, UnicodeDecodeError):
        return None


def section(markdown: str, heading: str) -> str:
    """The section of ``markdown`` titled ``heading`` (any level), without its heading line,
    up to the next heading of the same or a higher level; surrounding blank lines stripped.

    Raises
    ------
    KeyError
        When no heading has that title (or it occurs twice).
    """
    lines = markdown.splitlines()
    hits = [i for i, ln in enumerate(lines)
            if ln.startswith("#") and ln.lstrip("#").strip() == heading.strip()]
    if len(hits) != 1:
        raise KeyError(f"heading {heading!r} found {len(hits)} times (need exactly once)")
    start = hits[0]
    level = len(lines[start]) - len(lines[start].lstrip("#"))
    end = len(lines)
    for j in range(start + 1, len(lines)):
        ln = lines[j]
        if ln.startswith("#") and len(ln) - len(ln.lstrip("#")) <= level:
            end = j
            break
    return "\n".join(lines[start + 1:end]).strip("\n")


@dataclass(frozen=True)
class Quote:
    """One quote block of a README: its source ``path``, ``heading``, the ``body`` text and
    the 0-based line numbers of its ``begin`` and ``end`` markers."""

    path: str
    heading: str
    body: str
    begin: int
    end: int


def quotes(text: str) -> list[Quote]:
    """The quote blocks of a README text, in order.

    Raises
    ------
    ValueError
        On a begin marker without an end marker (or nested blocks).
    """
    lines = text.splitlines()
    out: list[Quote] = []
    i = 0
    while i < len(lines):
        m = _BEGIN.match(lines[i].strip())
        if m:
            for j in range(i + 1, len(lines)):
                if lines[j].strip() == _END:
                    break
                if _BEGIN.match(lines[j].strip()):
                    raise ValueError(f"line {j + 1}: quote block opened inside the one "
                                     f"opened on line {i + 1}")
            else:
                raise ValueError(f"line {i + 1}: quote block without {_END!r}")
            body = "\n".join(lines[i + 1:j]).strip("\n")
            out.append(Quote(m["path"], m["heading"], body, i, j))
            i = j
        i += 1
    return out


def _expected(q: Quote, root: Path) -> str:
    src = root / q.path
    if not src.is_file():
        raise FileNotFoundError(f"{q.path} (quoted on line {q.begin + 1}) does not exist")
    return section(src.read_text(encoding="utf-8"), q.heading)


def check_readme(readme: str | Path, root: str | Path | None = None) -> list[str]:
    """Problems of a README's quotes: one line per block that differs from (or cannot find)
    its file, and per measured-looking number in :data:`RESULTS_HEADING`'s section written
    outside a block. An empty list means every quoted number matches its file.

    Parameters
    ----------
    readme : path
        The README file.
    root : path, optional
        The directory the quoted paths are relative to (default: the README's).

    Returns
    -------
    list of str
        The problems, in file order.
    """
    readme = Path(readme)
    root = Path(root) if root is not None else readme.parent
    text = readme.read_text(encoding="utf-8")
    problems: list[str] = []
    blocks = quotes(text)
    for q in blocks:
        try:
            want = _expected(q, root)
        except (FileNotFoundError, KeyError) as exc:
            problems.append(f"line {q.begin + 1}: {exc}")
            continue
        if q.body != want:
            problems.append(f"line {q.begin + 1}: the quote of {q.path}#{q.heading} differs "
                            "from the file (run minimanc results update)")
    lines = text.splitlines()
    inside = set()
    for q in blocks:
        inside.update(range(q.begin, q.end + 1))
    in_results = False
    for i, ln in enumerate(lines):
        if ln.startswith("## "):
            in_results = ln.strip() == RESULTS_HEADING
            continue
        if in_results and i not in inside:
            for m in _MEASURED.finditer(ln):
                problems.append(f"line {i + 1}: the number {m.group(0)!r} is typed, not "
                                "quoted from a results file")
    return problems


def update_readme(readme: str | Path, root: str | Path | None = None) -> bool:
    """Rewrite every quote block of ``readme`` from its file; return whether it changed."""
    readme = Path(readme)
    root = Path(root) if root is not None else readme.parent
    text = readme.read_text(encoding="utf-8")
    lines = text.splitlines()
    for q in reversed(quotes(text)):
        lines[q.begin + 1:q.end] = _expected(q, root).splitlines()
    new = "\n".join(lines) + ("\n" if text.endswith("\n") else "")
    if new != text:
        write_text(readme, new)
    return new != text
