"""tools.semantics_system_dev: the whole system's dev figures and the ship rule a calibration change is judged by."""

import copy

from tools import semantics_system_dev as sd
from tools import train_semantics as ts


def _figures(over: dict | None = None) -> dict:
    base = dict(intent=0.9, acted=0.8, exact=0.8, none_held=1.0, confident_wrong=0.01, ece=0.04)
    res = {name: dict(base) for name in [*sd.SETS, *sd.POOLED]}
    res["blind hold-outs"]["confident_wrong"] = 0.0
    for (name, key), value in (over or {}).items():
        res[name][key] = value
    return res


def _failed(new: dict, old: dict) -> list[str]:
    return [text for text, ok in sd.ship_rule(new, old) if not ok]


def test_the_ship_rule_passes_only_a_change_that_lowers_the_unfitted_hold_outs_ece_and_costs_nothing_on_dev():
    old = _figures()
    better = _figures({(sd.UNFITTED, "ece"): 0.03})
    assert _failed(better, old) == []
    assert _failed(copy.deepcopy(old), old) == [f"{sd.UNFITTED} ECE 0.040 < 0.040"]  # no gain: no ship
    # the ninth session's situation temperature failed on these two clauses
    for key, value, clause in [
        (("v2 dev", "none_held"), 0.969, "v2 dev none_held 0.969 >= 1.000"),
        (("v2 + plain dev", "ece"), 0.05, "v2 + plain dev ECE 0.050 <= 0.040"),
        (("plain dev", "confident_wrong"), 0.02, "plain dev confident wrong 0.020 <= 0.010"),
        ((sd.UNFITTED, "intent"), 0.8, f"{sd.UNFITTED} intent 0.800 >= 0.900"),
        (
            ("blind hold-outs", "confident_wrong"),
            0.5,
            f"blind hold-outs confident wrong 0.500 <= {ts.SITUATION_TARGET_WRONG}",
        ),
    ]:
        new = copy.deepcopy(better)
        new[key[0]][key[1]] = value
        assert _failed(new, old) == [clause]


def test_a_set_without_no_motion_texts_skips_that_clause():
    old = _figures({("plain dev", "none_held"): None})
    new = _figures({("plain dev", "none_held"): None, (sd.UNFITTED, "ece"): 0.01})
    assert _failed(new, old) == []


def test_the_detector_rule_passes_only_a_detector_that_lowers_the_unfitted_hold_outs_ece_and_costs_nothing_else():
    old = _figures()
    better = _figures({(sd.UNFITTED_BOTH, "ece"): 0.03})
    assert [t for t, ok in sd.detector_rule(better, old) if not ok] == []
    same = [t for t, ok in sd.detector_rule(copy.deepcopy(old), old) if not ok]
    assert same == [f"{sd.UNFITTED_BOTH} ECE 0.040 < 0.040"]  # no gain: no ship
    for key, value, clause in [
        ((sd.NO_MOTION_DEV, "none_held"), 0.95, f"{sd.NO_MOTION_DEV} none_held 0.950 >= 1.000"),
        ((sd.NO_MOTION_DEV, "acted"), 0.7, f"{sd.NO_MOTION_DEV} acted 0.700 >= 0.800"),
        ((sd.NO_MOTION_DEV, "confident_wrong"), 0.02, f"{sd.NO_MOTION_DEV} confident wrong 0.020 <= 0.010"),
        ((sd.UNFITTED_BOTH, "acted"), 0.7, f"{sd.UNFITTED_BOTH} acted 0.700 >= 0.800"),
        (("blind hold-outs", "ece"), 0.05, "blind hold-outs ECE 0.050 <= 0.040"),
        (("v2 dev", "none_held"), 0.969, "v2 dev none_held 0.969 >= 1.000"),
        (
            ("blind hold-outs", "confident_wrong"),
            0.5,
            f"blind hold-outs confident wrong 0.500 <= {ts.SITUATION_TARGET_WRONG}",
        ),
    ]:
        new = copy.deepcopy(better)
        new[key[0]][key[1]] = value
        assert [t for t, ok in sd.detector_rule(new, old) if not ok] == [clause]


def test_the_pooled_figures_are_the_metrics_of_the_pooled_texts(monkeypatch):
    """evaluate() pools the texts of POOLED's sets (not their averages): one wrong text of 1 + 3 is 0.75."""
    import jgrounding as jg
    from jgrounding.semantics.types import Grounding

    sets = {"v2 dev": ["a"], "plain dev": ["b", "c", "d"], sd.UNFITTED: ["e"], sd.UNFITTED2: ["f"]}
    monkeypatch.setattr(sd, "SETS", {name: (name,) for name in sets})
    monkeypatch.setattr(
        sd, "read", lambda paths: [dict(text=t, intent="nodding", intensity="subtle") for t in sets[paths[0]]]
    )
    monkeypatch.setattr(
        jg, "ground", lambda t: Grounding("refusing" if t == "a" else "nodding", "subtle", 0.9, "embedded", True)
    )
    res = sd.evaluate()
    assert res["v2 dev"]["intent"] == 0.0 and res["plain dev"]["intent"] == 1.0
    assert res["v2 + plain dev"]["intent"] == 0.75 and res[sd.UNFITTED_BOTH]["n"] == 2
