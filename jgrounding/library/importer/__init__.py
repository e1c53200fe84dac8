"""Bring your own demonstrations: a folder of recorded trunk motions -> a library npz.

``python -m jgrounding.library import DIR --out my_library.npz [--controls P] [--simulate]``

Input: one file per demonstration in ``DIR`` and a manifest (``manifest.csv`` or ``manifest.json``).

- A demonstration is a CSV with a header row: a time column (``time``, ``time_s``, ``t``, ``timestamp``,
  ``elapsed`` or ``elapsed_s`` in seconds, ``time_ms``, ``t_ms``, ``timestamp_ms`` or ``elapsed_ms`` in
  milliseconds, any case; or ``--time-column``) and one column per tendon in the lab's own units; a ``step``
  or ``frame`` column is ignored, and ``#`` lines are comments. ``,``, ``;`` or a tab between cells and a
  UTF-8 byte-order mark are detected; with ``;`` or a tab, a decimal comma is read. The tendon columns are
  those of the first listed file with one column per declared limit (or the manifest's ``columns``); every
  file's are matched to them by name (any case), so another column order is mapped, never swapped, and a
  column not named as a tendon is ignored, with a note. A column that holds no numbers (a status flag, the
  empty column of a trailing delimiter) is never a tendon. The command streams that
  :mod:`jgrounding.apps.export` writes (``commands.csv`` / ``commands.json``) are demonstrations too.
- The manifest names, per file, its ``intent`` and ``intensity`` (names of :mod:`jgrounding.vocabulary`),
  optionally its response ``texts`` (a JSON list, or ``|``-separated in a CSV) and a ``realization`` id.
  A CSV manifest row with more cells than its header (a text with an unquoted comma) is an error that
  shows the row quoted. A JSON manifest may also declare the tendons' ``limits``: one ``[slack, full_pull]``
  pair per tendon in the lab's units (else ``--limits``), in the order of the tendon columns; their number
  is the number of tendons N_u.

What it does, in order (:mod:`jgrounding.library.importer.pipeline`): reads the manifest and every file it
lists, also the file of a bad manifest row, and reports every problem of the run together, each with its file,
line, column and a fix (the manifest line to delete included): bad manifest rows, bad cells, time that does
not increase, gaps in time, readings outside the limits by more than ``--tolerance`` (readings within it are
sensor noise, clipped to the limits, counted in the card and on the terminal), a stuck channel, a flat
recording, and a file whose time is in another unit than the others (:mod:`jgrounding.library.importer.checks`,
one function per check). It maps each tendon from its declared limits to [0, 1] (slack -> 0, full pull -> 1),
resamples linearly to T = 150 steps over the motion's own duration, optionally reduces by Eq. (ci)
(``--controls P``: ``u = make_safe(R(fit(u)))``, exactly like the built-in library), screens with
:func:`jgrounding.library.screening.screen` (bounds, slew, smoothness; and simulation on the 4-tendon trunk
with ``--simulate`` when the data are for our trunk model), splits every (intent, intensity) tuple into train
/ held-out realizations, and writes the npz and its card (:func:`jgrounding.library.save`, atomically).
``--drop-invalid`` drops bad files instead of stopping, lists every problem in the card and on the terminal,
and fails (exit 1, nothing written) when more than ``--max-dropped`` (default 20%) of the manifest's files
are left out.

Motion-capture markers: a JSON manifest may declare marker columns beside the tendon columns (``markers``,
``marker_units``, ``max_marker_gap_s``); they are checked with everything else (the map, the columns, gaps,
units, length: :mod:`jgrounding.library.importer.markers`) and named in the card; the library keeps the commands.

Modules, in the order of a run: ``manifest`` (the manifest's rows), ``parse`` (one file -> a table),
``checks`` (every check), ``markers`` (the marker map and the marker columns' checks), ``recording`` (one file
read and checked), ``pipeline`` (the folder), ``card`` (the arrays and the card), ``cli`` (the command line);
``errors`` holds the error types. Every public name is importable from here.
"""

from jgrounding.library.importer.card import LIBRARY_VERSION
from jgrounding.library.importer.checks import (
    FLAT_FRACTION,
    GAP_FACTOR,
    MIN_ROWS,
    STUCK_MOVING,
    STUCK_SECONDS,
    TOLERANCE,
    UNITS_RATIO,
)
from jgrounding.library.importer.cli import build_parser, config_from_args, main, parse_limits
from jgrounding.library.importer.errors import DemonstrationError, ImportProblems, TooManyDropped
from jgrounding.library.importer.manifest import (
    MANIFEST_NAMES,
    Entry,
    Manifest,
    Row,
    check_limits,
    find_manifest,
    manifest_unit,
    read_manifest,
)
from jgrounding.library.importer.parse import IGNORED_COLUMNS, TIME_COLUMNS, TIME_COLUMNS_MS, Table, read_table
from jgrounding.library.importer.pipeline import (
    MAX_DROPPED,
    TRUNK_TENDONS,
    ImportConfig,
    import_folder,
    normalize,
    resample,
)
from jgrounding.library.importer.recording import Recording, inspect_recording, read_recording

__all__ = [
    "FLAT_FRACTION",
    "GAP_FACTOR",
    "IGNORED_COLUMNS",
    "LIBRARY_VERSION",
    "MANIFEST_NAMES",
    "MAX_DROPPED",
    "MIN_ROWS",
    "STUCK_MOVING",
    "STUCK_SECONDS",
    "TIME_COLUMNS",
    "TIME_COLUMNS_MS",
    "TOLERANCE",
    "TRUNK_TENDONS",
    "UNITS_RATIO",
    "DemonstrationError",
    "Entry",
    "ImportConfig",
    "ImportProblems",
    "Manifest",
    "Recording",
    "Row",
    "Table",
    "TooManyDropped",
    "build_parser",
    "check_limits",
    "config_from_args",
    "find_manifest",
    "import_folder",
    "inspect_recording",
    "main",
    "manifest_unit",
    "normalize",
    "parse_limits",
    "read_manifest",
    "read_recording",
    "read_table",
    "resample",
]
