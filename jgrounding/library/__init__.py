"""The demonstration library: coded elephant primitives, response texts, simulation screening, and the
256-pair expert library built from them (``jg.load_library``)."""

from jgrounding.library.build import (  # noqa: F401  (re-exported: the library's public surface)
    ASSETS, DEFAULT_PATH, FORMAT_VERSION, REGENERATE, BuildConfig, Library, Split, build, file_hash, load_library,
    save, to_bytes,
)
