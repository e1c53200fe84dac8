"""End to end: the command line (subprocess) and the quick ablation."""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from experiments import ablation_result
from jgrounding import safety
from jgrounding.apps import export

ROOT = Path(__file__).resolve().parents[2]
ENV = {**os.environ, "JAX_PLATFORMS": "cpu", "PYTHONPATH": str(ROOT)}


def run(*args, timeout=300):
    return subprocess.run(
        [sys.executable, "-m", *args], cwd=ROOT, env=ENV, capture_output=True, text=True, timeout=timeout
    )


@pytest.mark.slow
def test_cli_grounds_samples_and_writes_files(tmp_path):
    out = tmp_path / "out"
    p = run(
        "jgrounding",
        "User seems sad; respond calmly with a gentle touch",
        "--samples",
        "4",
        "--out",
        str(out),
        "--seed",
        "1",
    )
    assert p.returncode == 0, p.stderr
    assert "comforting" in p.stdout
    for name in ("tendons.png", "posture.png", "motion.gif", "commands.csv", "commands.json", "samples.npy"):
        assert (out / name).stat().st_size > 1000 or name.endswith((".csv", ".json")), name
    header, u = export.read_command_stream_csv(out / "commands.csv")
    assert u.shape == (150, 4) and safety.is_safe(u)
    assert header["bounds"] == [0.0, 1.0] and header["intent"] == "comforting"
    doc = json.loads((out / "commands.json").read_text())
    np.testing.assert_allclose(np.array(doc["commands"]), u, atol=1e-5)
    assert np.load(out / "samples.npy").shape == (4, 150, 4)


def test_cli_jsonl_mode_and_direct_tuple(tmp_path):
    p = run(
        "jgrounding",
        "--intent",
        "nodding",
        "--intensity",
        "subtle",
        "--samples",
        "2",
        "--no-render",
        "--jsonl",
        "--out",
        str(tmp_path),
    )
    assert p.returncode == 0, p.stderr
    events = [json.loads(line) for line in p.stdout.splitlines()]
    assert events[0] == {"event": "tuple", "intent": "nodding", "intensity": "subtle"}
    assert any(e["event"] == "file" and e["kind"] == "csv" for e in events)


@pytest.mark.parametrize(
    "args, match",
    [
        (["--intent", "dancing"], "invalid choice"),
        (["hello", "--samples", "0"], "--samples"),
        (["hello", "--backend", "gpt4"], "invalid choice"),
        ([], "give a response text"),
        (["--intensity", "subtle"], "--intensity needs --intent"),
        (["hi", "--seed", "-3"], "--seed"),
    ],
)
def test_cli_usage_errors_exit_2_and_name_choices(args, match, capsys):
    from jgrounding.apps import cli

    with pytest.raises(SystemExit) as e:  # in-process: the parser is what is tested (the shell path: below)
        cli.main(args)
    err = capsys.readouterr().err
    assert e.value.code == 2 and match in err, err


def test_cli_usage_error_exits_2_from_the_shell():
    p = run("jgrounding", "--intent", "dancing", timeout=60)
    assert p.returncode == 2 and "invalid choice" in p.stderr and "nodding" in p.stderr, p.stderr


@pytest.mark.slow
def test_quick_ablation_end_to_end(tmp_path):
    # --steps 30 and K = 2 instead of the quick config's 300 and 8: the test checks the whole path and the rows,
    # not what 300 steps learn (the CNNs are deterministic regressors either way, the RF samples noise either
    # way); K = 2 (one sample of each variant) quarters the simulated samples and the reference rows' fresh
    # realizations; eval.physics_samples=1: the physics columns simulate the first of each tuple's 2 samples
    argv = [
        "--quick",
        "--steps",
        "30",
        "--set",
        "eval.num_samples=2",
        "--set",
        "eval.physics_samples=1",
        "--out",
        str(tmp_path),
    ]
    p = run("experiments.ablation", *argv, timeout=900)
    assert p.returncode == 0, p.stderr[-2000:]
    res = ablation_result.load(tmp_path)
    rows = res.rows
    assert set(rows) == {
        "raw_dense_cnn",
        "tuple_dense_cnn",
        "tuple_spline_cnn",
        "tuple_spline_ddpm",
        "tuple_spline_rf",
        "tuple_spline_rf_physics",
    }
    for r in rows.values():
        assert 0.0 <= r.success[0] <= 1.0 and 0.0 <= r.physics.feasible[0] <= 1.0 and r.time_ms > 0
        assert r.physics.samples == 64 * 1 * 2  # the first physics_samples of K_div, x 64 tuples x seeds
    cnn_div = max(rows[m].diversity[0] for m in rows if m.endswith("cnn"))
    assert cnn_div < 1e-6 < rows["tuple_spline_rf"].diversity[0]  # RF beats the CNNs on diversity
    assert (tmp_path / "ablation.md").read_text().count("|") > 50
    assert (tmp_path / "ablation.csv").read_text().count("\n") == 7
    cfg = res.config  # the whole composed config is recorded: the named entry with the run's overrides
    assert (cfg.train.steps, cfg.eval.num_samples, cfg.eval.seeds) == (30, 2, (0, 1))
    assert res.environment.cpu_count >= 1 and res.environment.cpu_isa


def test_interactive_loop_keeps_history(tmp_path):
    import io

    from jgrounding.apps import interact

    out = io.StringIO()
    interact.main(
        ["--out", str(tmp_path)], stdin=io.StringIO("Wave hello to the user!\n\n:history\n:quit\n"), stdout=out
    )
    text = out.getvalue()
    assert "-> (greeting," in text and "greeting/" in text.split(":history")[-1] + text
    assert (tmp_path / "turn001.png").stat().st_size > 1000


def test_cli_screen_and_current_flags(tmp_path):
    from jgrounding import sim

    p = run(
        "jgrounding",
        "--intent",
        "nodding",
        "--intensity",
        "emphatic",
        "--samples",
        "3",
        "--no-render",
        "--screen",
        "--current",
        "0.4,0,0.2,0",
        "--jsonl",
        "--out",
        str(tmp_path),
    )
    assert p.returncode == 0, p.stderr
    screen = [json.loads(line) for line in p.stdout.splitlines() if '"screen"' in line][0]
    assert screen["candidates"] >= 3 and 0 <= screen["rejected"] <= screen["candidates"] - 3
    u = np.load(tmp_path / "samples.npy")
    assert sim.feasible(sim.rollout(u)).all()
    assert safety.is_safe(u, current=np.array([0.4, 0, 0.2, 0])) and np.allclose(u[:, 0], [0.4, 0, 0.2, 0])
    bad = run("jgrounding", "--intent", "nodding", "--current", "0.4,2", "--out", str(tmp_path))
    assert bad.returncode == 2 and "--current must be 'rest' or comma-separated" in bad.stderr


def test_interactive_stream_of_responses_never_exceeds_the_slew_bound(tmp_path):
    import io

    from jgrounding.apps import interact

    said = "Wave hello to the user!\nShake your trunk: no!\nCurl up shyly.\nCelebrate wildly!\n:quit\n"
    interact.main(["--out", str(tmp_path)], stdin=io.StringIO(said), stdout=io.StringIO())
    stream = np.load(tmp_path / "stream.npy")  # every turn's command, in order, as sent to the robot
    assert stream.shape == (4 * 150 + safety.BLEND_STEPS + 1, 4)  # 4 turns, then the ramp back to rest
    assert not stream[-1].any()
    steps = np.abs(np.diff(np.concatenate([np.zeros((1, 4)), stream]), axis=0))  # from rest, across turns
    assert steps.max() <= safety.MAX_SLEW + 1e-6
