"""The docs' example model (docs/own_data.md), made small for tests: the shipped example recordings imported
as the page does, and a 10-step training run on them (the page trains 2000 steps)."""

from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
FOLDER = ROOT / "assets" / "examples" / "trunk_recordings"


def build(tmp: Path, steps: int = 10) -> tuple[Path, Path]:
    """``(library npz, checkpoint dir)`` under ``tmp``, made by the page's commands."""
    from experiments import train
    from jgrounding.library import importer

    lib, ckpt = tmp / "my_library.npz", tmp / "mine"
    assert importer.main(["import", str(FOLDER), "--out", str(lib), "--controls", "4", "--simulate"]) == 0
    assert train.main(["--library", str(lib), "--out", str(ckpt), "--steps", str(steps), "--chunk", str(steps)]) == 0
    return lib, ckpt
