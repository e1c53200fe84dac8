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
