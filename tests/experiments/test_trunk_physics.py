"""python -m experiments.trunk_physics: both trunks in one table, and a trunk identical to the shipped one gives the
hand-tuned column back exactly (samples, references, tolerance and screening alike)."""

import json
import shutil
from pathlib import Path

import pytest

from experiments import trunk_physics
from jgrounding.io import asset

RUNS = Path(__file__).resolve().parents[2] / "runs" / "ablation"


def test_bad_input_is_refused_naming_the_fix(tmp_path, capsys):
    with pytest.raises(SystemExit):
        trunk_physics.main(["--trunk", str(tmp_path / "absent.xml"), "--runs", str(tmp_path)])
    assert "not found" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        trunk_physics.main(["--trunk", str(asset("trunk.xml")), "--runs", str(tmp_path), "--methods", "nope"])
    assert "no checkpoint" in capsys.readouterr().err and not (tmp_path / "out.md").exists()


@pytest.mark.slow
@pytest.mark.skipif(
    not (RUNS / "tuple_spline_cnn" / "meta.json").is_file(),
    reason="needs the ablation's checkpoints in runs/ablation (python -m experiments.ablation saves them; a clean "
    "clone has no runs/)",
)
def test_a_copy_of_the_shipped_trunk_reproduces_the_hand_tuned_column(tmp_path):
    same = shutil.copy(asset("trunk.xml"), tmp_path / "same.xml")
    out = tmp_path / "trunk_physics"
    args = ["--trunk", str(same), "--runs", str(RUNS), "--methods", "tuple_spline_cnn", "--per-tuple", "1"]
    assert trunk_physics.main([*args, "--ablation", str(tmp_path), "--out", str(out)]) == 0
    res = json.loads(out.with_suffix(".json").read_text())
    assert res["trunks"]["fitted"]["path"] == str(same)
    assert res["trunks"]["fitted"]["sha256"] == res["trunks"]["hand_tuned"]["sha256"]
    assert set(res["methods"]) == {"tuple_spline_cnn"} and set(res["references"]) == {
        "oracle",
        "wrong_intent_any_intensity",
        "tuple_mean",
    }
    for row in [*res["methods"].values(), *res["references"].values()]:
        for field, _, _ in trunk_physics.COLUMNS:
            assert row["hand_tuned"][field] == row["fitted"][field]
    phys = res["methods"]["tuple_spline_cnn"]["hand_tuned"]
    assert phys["samples"] == 5 * 64 and 0 < phys["shape_success"][0] < 1 and phys["feasible"][0] > 0.9
    assert res["screening"]["hand_tuned"] == res["screening"]["fitted"]
    assert res["screening"]["fitted"]["per_intent"]["all"]["demonstrations"] == 256
    assert "not comparable" in res["ablation"]["note"]  # 1 sample per tuple, Table II simulates 10
    text = out.with_suffix(".md").read_text()
    assert "Shape succ. hand-tuned | Shape succ. fitted" in text and "| Tuple + Spline + CNN |" in text
    assert "| all | 256 |" in text and "stay feasible" in text
