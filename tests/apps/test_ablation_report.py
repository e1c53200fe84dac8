"""The ablation's report module renders the committed results/ablation.{md,csv} from results/ablation.json alone
(issue #22: run and report split), through the one typed loader (issue #33): the table in the repository is what
the report code makes of the recorded run, and a file of another schema is refused with how to regenerate it."""

import dataclasses
import json
from pathlib import Path

import pytest

from experiments import ablation_report, ablation_result

RESULTS = Path(__file__).resolve().parents[2] / "results"


@pytest.fixture(scope="module")
def recorded():
    return ablation_result.load(RESULTS)


def test_the_committed_table_is_the_report_of_the_recorded_run(recorded):
    assert ablation_report.render(recorded) == (RESULTS / "ablation.md").read_text()
    assert ablation_report.table_csv(recorded) == (RESULTS / "ablation.csv").read_bytes().decode()  # \r\n kept


def test_the_report_reads_the_run_settings_from_its_composed_config(recorded):
    cfg = dataclasses.replace(recorded.config.eval, seeds=(0, 1), num_samples=8)
    res = dataclasses.replace(recorded, config=dataclasses.replace(recorded.config, eval=cfg))
    assert ablation_report.markdown(res).startswith("Ablation (Table II), 2 seeds, 10000 steps, K_div = 8, tau = 0.35")


def test_a_result_survives_save_and_load(recorded, tmp_path):
    ablation_result.save(recorded, tmp_path)
    back = ablation_result.load(tmp_path)
    assert back == recorded  # every field but the arrays, which compare below
    assert back.per_sample_rms.keys() == recorded.per_sample_rms.keys()
    assert all((back.per_sample_rms[k] == v).all() for k, v in recorded.per_sample_rms.items())
    assert isinstance(back.rows["tuple_spline_rf"].physics, ablation_result.Physics)
    assert back.references["oracle"].success[0.35] == recorded.references["oracle"].success[0.35]  # float keys


def test_a_file_of_the_old_schema_says_how_to_regenerate_it(recorded, tmp_path):
    ablation_result.save(recorded, tmp_path)
    old = json.loads((tmp_path / "ablation.json").read_text())
    del old["schema"]  # schema 1 had no version field
    (tmp_path / "ablation.json").write_text(json.dumps(old))
    with pytest.raises(ValueError, match=r"schema 1 .* reads schema 2\. Regenerate it: make ablation"):
        ablation_result.load(tmp_path)


def test_a_field_of_another_shape_is_named(recorded):
    data = json.loads(ablation_result.to_json(recorded))
    del data["rows"]["tuple_spline_rf"]["physics"]["seconds"]
    with pytest.raises(ValueError, match=r"rows\[tuple_spline_rf\]\.physics: expected the fields"):
        ablation_result.from_json(json.dumps(data))


def test_a_missing_result_names_the_command(tmp_path):
    with pytest.raises(FileNotFoundError, match="ablation.json and .*ablation_rms.npz not found: run make ablation"):
        ablation_result.load(tmp_path)


def _with_rounds(res, rf_rounds, ddpm_rounds):
    from jgrounding.evaluation import latency

    rows = dict(res.rows)
    for name, rounds in (("tuple_spline_rf", rf_rounds), ("tuple_spline_ddpm", ddpm_rounds)):
        med, lo, hi = latency.median_interval(rounds)
        rows[name] = dataclasses.replace(
            rows[name], time_ms=med, time_rounds_ms=tuple(rounds), time_interval_ms=(lo, hi)
        )
    return dataclasses.replace(res, rows=rows)


def _time_sentence(res):
    (line,) = [f for f in ablation_report.findings(res) if f.startswith("RF vs DDPM time")]
    return line


def test_the_rf_vs_ddpm_time_sentence_follows_the_paired_test_over_rounds(recorded):
    ddpm = [0.80 + 0.01 * i for i in range(10)]
    faster = _time_sentence(_with_rounds(recorded, [x * 0.8 for x in ddpm], ddpm))
    assert "RF faster in 10 of 10 interleaved rounds" in faster and ": RF faster (the paper" in faster
    # a lower median alone does not make RF faster: here it is lower by one drifting round's luck
    mixed = [x * (0.97 if i % 2 else 1.02) for i, x in enumerate(ddpm)]
    assert ": RF not distinguishable" in _time_sentence(_with_rounds(recorded, mixed, ddpm))
    assert ": RF slower" in _time_sentence(_with_rounds(recorded, [x * 1.2 for x in ddpm], ddpm))
    # a run timed one method after the other is reported as untested, never as a verdict
    old = _with_rounds(recorded, ddpm, ddpm)
    old = dataclasses.replace(
        old, rows={k: dataclasses.replace(v, time_rounds_ms=(), time_interval_ms=()) for k, v in old.rows.items()}
    )
    assert "not interleaved: untested" in _time_sentence(old)


def test_a_file_written_before_the_interleaved_time_still_loads(recorded):
    data = json.loads(ablation_result.to_json(recorded))
    for row in data["rows"].values():
        row.pop("time_rounds_ms", None)
        row.pop("time_interval_ms", None)
    data["timing"].pop("latency_s", None)
    back = ablation_result.from_json(json.dumps(data))
    assert all(r.time_rounds_ms == () for r in back.rows.values()) and back.timing.latency_s is None
    data["rows"]["tuple_spline_rf"]["time_ms_typo"] = 1.0  # an unknown field is still refused
    with pytest.raises(ValueError, match="expected the fields"):
        ablation_result.from_json(json.dumps(data))


def test_a_file_written_before_physics_samples_says_every_sample_was_simulated(recorded):
    data = json.loads(ablation_result.to_json(recorded))
    data["config"]["eval"].pop("physics_samples", None)  # the field came with issue #37
    back = dataclasses.replace(ablation_result.from_json(json.dumps(data)), per_sample_rms=recorded.per_sample_rms)
    assert back.config.eval.physics_samples == back.config.eval.num_samples
    assert "every generated sample (K_div = 30 × 64 per method and seed) simulated" in ablation_report.render(back)
    data["config"]["eval"]["physics_samples"] = 10
    sub = dataclasses.replace(ablation_result.from_json(json.dumps(data)), per_sample_rms=recorded.per_sample_rms)
    assert "the first 10 of each tuple's K_div = 30 i.i.d. samples" in ablation_report.render(sub)
