"""tools/readme.py: the README's headline block, docs/results.md and docs/semantics.md are generated from results/
and current; the generator works from whatever results/ holds (a re-run on another stack, a partial run, none)."""

import json

import pytest

from tools import readme


def test_the_readme_is_short_and_its_headline_block_is_current():
    text = (readme.ROOT / "README.md").read_text()
    assert len(text.splitlines()) <= 250, "README.md is for a newcomer: keep it within 250 lines"
    start, end = readme.HEADLINE
    body = text.split(start, 1)[1].split(end, 1)[0].strip()
    assert body == readme.headline().strip(), "README.md's results are stale: run `python -m tools.readme`"


@pytest.mark.parametrize("page", ["results", "semantics"])
def test_generated_pages_are_current(page):
    made = readme.results_page() if page == "results" else readme.semantics_page()
    assert (readme.ROOT / "docs" / f"{page}.md").read_text() == made, (
        f"docs/{page}.md is stale: run `python -m tools.readme`"
    )


ABLATION = """Ablation (Table II), 2 seeds, 10 steps.

| Method | Succ. | Succ. (all samples) | Div. | Time (ms) | Paper Succ. / Div. / Time |
|---|---|---|---|---|---|
| Tuple + Spline + RF | 0.700 ± 0.010 | 0.690 ± 0.010 | 0.190 ± 0.010 | 0.40 [0.39, 0.44] | 0.772 / 0.148 / 4.87 |
| Oracle (replay same tuple) | 0.669 ± 0.041 | – | – | – | – |

- RF vs DDPM success (one sample per tuple): 0.700 vs 0.600; Welch t = 5.0, p = 0.003: RF higher. More words.
- Something else: not a claim.
"""


def test_pages_follow_whatever_results_hold(tmp_path, monkeypatch):
    monkeypatch.setattr(readme, "RESULTS", tmp_path)
    assert "No results yet" in readme.headline() and "No results yet" in readme.semantics_page()
    assert "## Table II" not in readme.results_page()
    (tmp_path / "ablation.md").write_text(ABLATION)
    head = readme.headline()
    assert "| Tuple + Spline + RF | 0.700 ± 0.010 | 0.190 ± 0.010 | 0.40 [0.39, 0.44] | 0.772 / 0.148 / 4.87 |" in head
    assert "Oracle" not in head  # a reference row, not a method of the paper
    assert "- RF vs DDPM success (one sample per tuple): 0.700 vs 0.600; Welch t = 5.0, p = 0.003: RF higher." in head
    assert "More words" not in head and "Something else" not in head
    assert "## Table II: ablation" in readme.results_page()
    bench = {
        "metrics": {"new|x1 bench|all": {"n": 10}, "new|y2 bench|all": {"n": 20}},
        "goals_34": {
            "x1 bench: intent >= 0.9": {"met": True, "measured": "0.950", "second_reader": "1.000"},
            "x1 bench: ECE <= 0.05": {"met": False, "measured": "0.070"},
            "y2 bench: ECE <= 0.05": {"met": True, "measured": "0.010"},
        },
    }
    (tmp_path / "bench_semantics.json").write_text(json.dumps(bench))
    page = readme.semantics_page()
    assert "| set | texts | intent >= 0.9 | ECE <= 0.05 |" in page
    assert "| x1 bench | 10 | 0.950 (1.000) | **0.070** ✗ |" in page
    assert "| y2 bench | 20 |  | 0.010 |" in page
    assert "2 of 3 cells meet their goal" in page
    assert page.count("| set |") == 1  # one table of sets x goals


def test_a_readme_without_the_markers_is_refused(tmp_path):
    bad = tmp_path / "README.md"
    bad.write_text("# no markers\n")
    with pytest.raises(ValueError, match="headline:start"):
        readme.update(bad, tmp_path / "v.md", tmp_path / "r.md", tmp_path / "s.md")
