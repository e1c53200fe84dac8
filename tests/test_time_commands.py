"""tools/time_commands.py: the README commands' times in docs/testing.md come from its records, not typed in."""

import pytest

from tools import time_commands


def _record(**kw):
    base = dict(
        command="make test",
        name="test",
        rc=0,
        wall_s=175.7,
        pytest="565 passed, 1 xfailed in 105.36s",
        xla_flags="--xla_cpu_max_isa=AVX2",
        commit="abc1234",
        date="2026-12-03T19:40:00",
        cpu="Intel(R) Xeon(R) Processor",
        isa="avx512f",
        cores=2,
    )
    return {**base, **kw}


def test_the_pytest_summary_is_the_last_result_line():
    out = "collected\n== 3 failed, 2 passed in 1.00s ==\nmore\n=== 565 passed, 1 xfailed, 2 warnings in 105.36s (0:01:45) ===\n"
    assert time_commands.pytest_summary(out) == "565 passed, 1 xfailed, 2 warnings in 105.36s (0:01:45)"
    assert time_commands.pytest_summary("no tests here") == ""


def test_the_table_keeps_the_latest_record_per_command_and_says_whether_the_goal_is_met():
    old = _record(wall_s=400.0, date="2026-12-02T10:00:00")
    new = _record()
    slow = _record(name="ablation", command="make ablation", wall_s=1305.0, pytest="")
    text = time_commands.table([old, new, slow])
    assert "6 min 40 s" not in text and "2 min 56 s" in text  # the older record of the same command is replaced
    assert "<= 6 min: met" in text and "<= 12 min: not met" in text
    assert "2-core Intel(R) Xeon(R) Processor (avx512f)" in text
    failed = time_commands.table([_record(rc=1)])
    assert "not met" in failed  # a red run never meets its goal


def test_the_doc_block_is_regenerated_and_the_rest_kept(tmp_path):
    doc = tmp_path / "testing.md"
    doc.write_text(f"before\n{time_commands.START}\nstale\n{time_commands.END}\nafter\n")
    time_commands.update_doc([_record()], doc)
    text = doc.read_text()
    assert text.startswith("before\n") and text.endswith("after\n") and "stale" not in text and "2 min 56 s" in text
    doc.write_text("no markers")
    with pytest.raises(ValueError, match="no <!-- timings:start -->"):
        time_commands.update_doc([], doc)
