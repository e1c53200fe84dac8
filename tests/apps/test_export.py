import json

import numpy as np
import pytest

from jgrounding import io
from jgrounding.apps import export


def test_command_stream_round_trip(tmp_path):
    u = 0.5 + 0.4 * np.sin(np.linspace(0, 3, 150))[:, None] * np.ones(4)
    path = io.write_atomic(
        tmp_path / "c.csv", export.command_stream_csv(u, control_dt=1 / 30, meta={"intent": "nodding"})
    )
    header, back = export.read_command_stream_csv(path)
    np.testing.assert_allclose(back, u, atol=1e-6)
    assert header["control_rate_hz"] == pytest.approx(30.0) and header["intent"] == "nodding"
    doc = json.loads(export.command_stream_json(u, control_dt=1 / 30))
    assert len(doc["commands"]) == 150 and doc["header"]["bounds"] == [0.0, 1.0]


def test_unsafe_commands_are_made_safe_or_refused():
    u = np.full((150, 4), 2.0)
    rows = export.command_stream_csv(u, control_dt=0.1).split("step,time_s")[1].strip().splitlines()[1:]
    values = np.array([[float(x) for x in row.split(",")[2:]] for row in rows])
    assert values.shape == (150, 4) and values.min() >= 0.0 and values.max() <= 1.0  # clamped, not passed
    with pytest.raises(ValueError, match="non-finite"):
        export.command_stream_csv(np.full((150, 4), np.nan), control_dt=0.1)


def test_atomic_write_leaves_no_temp_files(tmp_path):
    io.write_atomic(tmp_path / "a.txt", "x")
    io.write_atomic(tmp_path / "a.txt", "y")
    assert (tmp_path / "a.txt").read_text() == "y" and len(list(tmp_path.iterdir())) == 1
