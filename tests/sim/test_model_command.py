"""``python -m jgrounding.sim.model`` writes the shipped trunk.xml byte for byte, and warns about nothing (the
package imports the builder, jgrounding.sim.mjcf, never the command's module, so runpy imports nothing twice)."""

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_the_model_command_rewrites_trunk_xml_without_a_warning(tmp_path):
    out = tmp_path / "trunk.xml"
    cmd = [sys.executable, "-W", "error", "-m", "jgrounding.sim.model", "--out", str(out)]
    done = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert "Warning" not in done.stderr, done.stderr
    assert out.read_bytes() == (ROOT / "jgrounding" / "assets" / "trunk.xml").read_bytes()
