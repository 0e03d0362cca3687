"""Chapter 0 — the notebook machinery: solutions → exercises, execution and grading.

The graded notebooks follow nbgrader's conventions without its database:

* ``solutions/`` is the only hand-edited source of graded sets. The code a student
  must write sits between ``### BEGIN SOLUTION`` and ``### END SOLUTION`` in a
  *solution cell* (metadata ``nbgrader.solution = true``, ``grade_id`` = the
  exercise id, ``minimanc.title`` = its title).
* *Grade cells* (``nbgrader.grade = true``, ``grade_id``, ``points``) hold asserts;
  tests a student should not see sit between ``### BEGIN HIDDEN TESTS`` and
  ``### END HIDDEN TESTS``.
* :func:`build` turns every solution region into
  ``raise NotImplementedError("Exercise <id>: <title>")`` at the marker's
  indentation, removes hidden tests, clears outputs and tags the cells that will
  raise ``raises-exception`` (honoured by nbval), writing ``exercises/``.
* Every graded notebook carries notebook metadata ``minimanc.assignment`` (its
  solutions file's stem); exercise notebooks also carry ``source_sha256``, the
  fingerprint of the tests they were built from.
* A written answer graded by hand is a markdown *answer cell* (nbgrader's manually
  graded answer: ``solution`` and ``grade`` true, ``task`` false, ``points``); its
  model answer sits between the solution markers and :func:`build` replaces it
  with ``YOUR ANSWER HERE``.
* :func:`grade` executes a notebook and scores each grade cell against the
  authoritative grade cells (hidden tests included) of
  ``solutions/<assignment>.ipynb``, never against the notebook's own. A
  solution cell may list library functions it asks the student to write
  (``minimanc.forbids``); they raise while that exercise's grade cells run
  (:func:`shadow`). The grade cells run in a process of their own that no student
  cell reaches (:mod:`~minimanc.exercises.checker`); the notebook answers their calls
  with plain data (:mod:`~minimanc.exercises.serving`,
  :mod:`~minimanc.exercises.values`). Written answers are listed apart, "to grade by
  hand", never in the automatic total.

Notebooks are authored in the "percent" format (:func:`convert`), see
CONTRIBUTING.md.

The package has one module per job, and every name is re-exported here:
:mod:`~minimanc.exercises.markers` (markers, metadata, validation),
:mod:`~minimanc.exercises.builder` (solutions → exercises),
:mod:`~minimanc.exercises.conversion` (percent format, execution),
:mod:`~minimanc.exercises.grading` (grading), :mod:`~minimanc.exercises.checker` (the
tests' process), :mod:`~minimanc.exercises.serving` (the notebook's answers),
:mod:`~minimanc.exercises.wire` with :mod:`~minimanc.exercises.values`,
:mod:`~minimanc.exercises.encoding` and :mod:`~minimanc.exercises.decoding` (what crosses
between them, and how) and :mod:`~minimanc.exercises.shadowing` (library shadowing).
"""

from __future__ import annotations

from minimanc.exercises.builder import (
    build,
    make_exercise,
)
from minimanc.exercises.checker import instrument_grade_source
from minimanc.exercises.conversion import (
    KERNEL_ARGS,
    TIMEOUT_ENAME,
    cells_from_percent,
    convert,
    run,
)
from minimanc.exercises.grading import (
    DEFAULT_TIMEOUT,
    AnswerRow,
    GradeRefused,
    GradeReport,
    GradeRow,
    answer_names,
    assignment_of,
    exercise_of_grade_cells,
    find_source,
    forbidden_functions,
    grade,
    read_notebook,
)
from minimanc.exercises.markers import (
    ANSWER_PLACEHOLDER,
    BEGIN_HIDDEN,
    BEGIN_SOLUTION,
    END_HIDDEN,
    END_SOLUTION,
    META_KEY,
    RAISES_TAG,
    NotebookFormatError,
    answer_written,
    assignment_name,
    grade_id,
    is_answer_cell,
    is_grade_cell,
    is_solution_cell,
    source_fingerprint,
    strip_hidden,
    stub_answer,
    stub_solution,
    validate,
)
from minimanc.exercises.shadowing import (
    ForbiddenFunctionError,
    Shadow,
    resolve,
    shadow,
)
from minimanc.exercises.values import RefusedAnswer

__all__ = [
    "ANSWER_PLACEHOLDER",
    "AnswerRow",
    "BEGIN_HIDDEN",
    "BEGIN_SOLUTION",
    "DEFAULT_TIMEOUT",
    "END_HIDDEN",
    "END_SOLUTION",
    "ForbiddenFunctionError",
    "GradeRefused",
    "GradeReport",
    "GradeRow",
    "KERNEL_ARGS",
    "META_KEY",
    "NotebookFormatError",
    "RAISES_TAG",
    "RefusedAnswer",
    "Shadow",
    "TIMEOUT_ENAME",
    "answer_names",
    "answer_written",
    "assignment_name",
    "assignment_of",
    "build",
    "cells_from_percent",
    "convert",
    "exercise_of_grade_cells",
    "find_source",
    "forbidden_functions",
    "grade",
    "grade_id",
    "instrument_grade_source",
    "is_answer_cell",
    "is_grade_cell",
    "is_solution_cell",
    "make_exercise",
    "read_notebook",
    "resolve",
    "run",
    "shadow",
    "source_fingerprint",
    "strip_hidden",
    "stub_answer",
    "stub_solution",
    "validate",
]
