"""tools.semantics_system_dev: the whole system's dev figures and the ship rule a calibration change is judged by."""

import copy

from tools import semantics_system_dev as sd
from tools import train_semantics as ts


def _figures(over: dict | None = None) -> dict:
    base = dict(intent=0.9, acted=0.8, exact=0.8, none_held=1.0, confident_wrong=0.01, ece=0.04)
    res = {name: dict(base) for name in sd.SETS}
    res["v2 + plain dev"] = dict(base)
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
