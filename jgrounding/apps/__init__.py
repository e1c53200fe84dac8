"""Front doors: the command line (``python -m jgrounding``), the interactive loop
(``python -m jgrounding.apps.interact``), command-stream export and plotting."""
