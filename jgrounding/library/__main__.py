"""``python -m jgrounding.library import DIR --out my_library.npz``: import recorded demonstrations."""

from jgrounding.library.importer import main

raise SystemExit(main())
