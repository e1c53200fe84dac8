"""``python -m jgrounding.library import DIR --out my_library.npz``: import recorded demonstrations."""

from jgrounding.library import importer

raise SystemExit(importer.main())
