"""`python -m experiments.ablation --folds 4` end to end on one tiny fold (issue #22: the option crashed at its
first import and no test ran it)."""

import dataclasses
import json

import pytest

from experiments import ablation


@pytest.mark.slow  # ~36 s at load average 10 on 2 cores (13 s of CPU)
def test_one_fold_of_the_cross_validation_runs_end_to_end(tmp_path, monkeypatch, capsys):
    # The tiniest configuration that still trains, samples, simulates and pools: 1 seed, 5 steps, 2 samples of 4
    # Euler steps. The fold's library drops its evaluation set, which skips the distribution rows (their fresh
    # realizations are screened in simulation, about a minute); those run in test_quick_ablation_end_to_end.
    fold = ablation.library.fold
    monkeypatch.setattr(ablation.library, "fold", lambda lib, k: dataclasses.replace(fold(lib, k), evaluation=None))
    out = tmp_path / "folds"
    argv = ["--folds", "4", "--only-fold", "1", "--quick", "--methods", "tuple_spline_rf", "--no-physics-aware"]
    tiny = ["--set", "eval.num_samples=2", "--set", "sample.steps=4"]
    assert ablation.main([*argv, *tiny, "--seeds", "0", "--steps", "5", "--out", str(out)]) == 0
    res = json.loads((out / "ablation_folds.json").read_text())
    assert res["folds"] == 4 and res["only_fold"] == 1
    cfg = res["config"]
    assert cfg["eval"]["rows"] == ["tuple_spline_rf"] and cfg["eval"]["runs"] == str(out / "runs")
    assert cfg["eval"]["num_samples"] == 2 and cfg["sample"]["steps"] == 4 and cfg["train"]["steps"] == 5
    row = res["rows"]["tuple_spline_rf"]
    assert len(row["per_fold"]) == 1 and 0.0 <= row["success"][0] <= 1.0
    assert (out / "runs" / "fold1" / "tuple_spline_rf").is_dir()  # the fold's checkpoint, apart from other folds
    table = (out / "ablation_folds.md").read_text()
    assert "fold 1 only (64 targets)" in table and "| Tuple + Spline + RF |" in table and "Oracle" in table
    assert "fold 1: tuple_spline_rf" in capsys.readouterr().out


def test_only_fold_needs_folds(capsys):
    with pytest.raises(SystemExit) as e:
        ablation.main(["--only-fold", "0"])
    assert e.value.code == 2 and "--only-fold needs --folds 4" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        ablation.main(["--folds", "4", "--only-fold", "4"])  # folds are 0..3
    assert "invalid choice" in capsys.readouterr().err
