"""The ablation's report module renders the committed results/ablation.md from results/ablation.json alone (issue
#22: run and report split): the table in the repository is what the report code makes of the recorded run."""

from pathlib import Path

from experiments import ablation_report

RESULTS = Path(__file__).resolve().parents[2] / "results"


def test_the_committed_table_is_the_report_of_the_recorded_run():
    res = ablation_report.load(RESULTS)
    assert ablation_report.render(res) == (RESULTS / "ablation.md").read_text()


def test_settings_read_the_composed_config_and_the_older_flat_one():
    nested = {
        "config": {
            "train": {"steps": 300},
            "sample": {"steps": 50},
            "eval": {"seeds": [0, 1], "num_samples": 8, "tau": 0.35, "library": None, "rows": [], "runs": "r"},
        },
        "rows_run": ["tuple_spline_rf"],
    }
    got = ablation_report.settings(nested)
    assert (got["steps"], got["k_div"], got["euler_steps"], got["methods"]) == (300, 8, 50, ["tuple_spline_rf"])
    flat = {"config": {"seeds": [0], "steps": 10, "k_div": 2, "tau": 0.35, "euler_steps": 4}}
    assert ablation_report.settings(flat)["k_div"] == 2
