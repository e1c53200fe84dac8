"""The demonstration library: coded elephant primitives, response texts, simulation screening, the
256-pair expert library built from them (``jg.load_library``), its brackets, and the importer of a
lab's own recordings (:mod:`jgrounding.library.importer`, ``python -m jgrounding.library import DIR``)."""

from jgrounding.library.build import (  # noqa: F401  (re-exported: the library's public surface)
    ASSETS,
    BRACKET_RANGES,
    DEFAULT_PATH,
    FORMAT_VERSION,
    LIBRARY_VERSION,
    REGENERATE,
    TUPLE_MEAN_GAP,
    BuildConfig,
    EvalSet,
    Library,
    Split,
    bracket_distances,
    bracket_violations,
    brackets,
    build,
    content_hash,
    file_hash,
    fold,
    fresh_realizations,
    heldout_overlap,
    load_library,
    save,
    to_bytes,
    variant_midpoint,
    with_all_pairs,
)
