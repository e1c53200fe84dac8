"""scripts/device_check.sh --tiny: the accelerator check runs end to end on the CPU."""

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def test_device_check_tiny_runs_every_part_and_writes_its_report(tmp_path):
    out = tmp_path / "gpu.md"
    env = {**os.environ, "PY": sys.executable}
    done = subprocess.run(
        ["bash", str(ROOT / "scripts" / "device_check.sh"), "--tiny", "--out", str(out)],
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    text = out.read_text()
    assert "Tiny run (CI)" in text and "not accelerator figures" in text
    for section in ("Rollout throughput", "Sampler on this device", "Ablation physics columns"):
        assert section in text
    rows = [line for line in text.splitlines() if line.startswith("| ") and not line.startswith("| B ")]
    assert sum(line.startswith(("| native | 8 ", "| native | 16 ")) for line in rows) == 2  # both tiny batches
    assert any(line.startswith("| native | 0.") for line in rows)  # the physics columns
    assert "#### Goals" in text and "No accelerator engine ran" in text
    assert "nan" not in text.lower()
