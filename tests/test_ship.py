"""experiments.ship: each step count is served by its best (checkpoint, guidance, noise scale), one guidance per
checkpoint, chosen on one half of the tuples and reported on the other."""

import numpy as np

from experiments import ship

RF, MF, SC = ship.DEFAULT, ship.MEANFLOW, ship.SHORTCUT


def test_each_s_gets_its_winner_with_one_guidance_per_checkpoint():
    scores = {  # (S, checkpoint, w, T) -> score
        (50, RF, 0.0, 1.0): 0.90,
        (50, RF, 0.5, 1.15): 0.95,
        (50, MF, 0.0, 1.0): 0.99,  # the default serves the largest S
        (1, RF, 0.5, 1.0): 0.2,
        (1, RF, 0.0, 1.0): 0.5,
        (1, MF, 0.0, 1.0): 0.8,
        (1, MF, 0.5, 1.0): 0.3,
        (1, SC, 1.0, 1.0): 0.1,
        (2, RF, 0.5, 1.0): 0.85,
        (2, MF, 0.0, 1.3): 0.8,  # MF at its fixed w = 0, at another noise scale than at S = 1
        (2, MF, 0.5, 1.0): 0.9,  # MF is fixed at w = 0 by S = 1: RF wins
        (4, MF, 0.0, 1.45): 0.9,  # the noise scale is free per S
        (4, RF, 0.5, 1.0): 0.88,
    }
    table = [(s, n, w, t, {"score": sc}, sc) for (s, n, w, t), sc in scores.items()]
    served, fixed = ship.assign(table, (1, 2, 4, 50))
    assert {s: v[:3] for s, v in served.items()} == {
        50: (RF, 0.5, 1.15),
        1: (MF, 0.0, 1.0),
        2: (RF, 0.5, 1.0),
        4: (MF, 0.0, 1.45),
    }
    assert served[1][3] == {"score": 0.8}
    assert fixed == {RF: 0.5, MF: 0.0, SC: 1.0}  # SC serves nothing: its best w at the smallest S


def test_a_candidate_outside_the_mm_window_ranks_below_every_one_inside():
    inside = {"prec_r": 0.5, "mode_cov": 0.5, "intent_ret": 0.5, "intensity_ret": 0.5, "mm_ratio": 1.19}
    precise_but_collapsed = {**inside, "prec_r": 1.0, "mode_cov": 1.0, "mm_ratio": 0.79}
    assert ship.rank(inside) == 0.5 > ship.rank(precise_but_collapsed)
    # outside, the nearer to the window ranks higher
    assert ship.rank({**precise_but_collapsed, "mm_ratio": 0.7}) < ship.rank(precise_but_collapsed)


def test_the_halves_split_every_intent_and_intensity():
    intent, intensity = np.repeat(np.arange(16), 4), np.tile(np.arange(4), 16)
    h = ship.halves(intent, intensity)
    assert len(h["choice"]) == len(h["report"]) == 32 and not set(h["choice"]) & set(h["report"])
    for half in ("choice", "report"):
        assert set(intent[h[half]]) == set(range(16)) and set(intensity[h[half]]) == set(range(4))
    assert h["all"].tolist() == list(range(64))


def test_the_report_checks_each_s_against_the_largest_and_shows_t_1():
    def metrics(prec, mm, inten=0.96):
        return {
            "prec_r": prec,
            "mode_cov": 1.0,
            "mm_ratio": mm,
            "intent_ret": 0.99,
            "intensity_ret": inten,
            "between": 0,
        }

    scores = {
        "2": {"checkpoint": MF, "guidance": 0.0, "noise_scale": 1.4, **metrics(0.93, 0.85)},  # 0.03 below S = 50
        "4": {"checkpoint": MF, "guidance": 0.0, "noise_scale": 1.3, **metrics(0.95, 0.88)},
        "8": {"checkpoint": MF, "guidance": 0.0, "noise_scale": 1.0, **metrics(0.97, 0.75)},  # under-dispersed
        "50": {"checkpoint": RF, "guidance": 0.25, "noise_scale": 1.1, **metrics(0.96, 0.82)},
    }
    for m in scores.values():
        m["all_tuples"] = dict(m)
    candidates = [
        {"steps": 4, "checkpoint": MF, "guidance": 0.0, "noise_scale": 1.0, "report_half": metrics(0.98, 0.7)}
    ]
    fresh = {s: {m: [0.9, 0.9] for m in ship.FRESH} for s in ("2", "50")}
    fresh["2"]["prec_r"], fresh["50"]["prec_r"] = [0.95, 0.93], [0.96, 0.96]
    text = ship.report(
        {"scores": scores, "candidates": candidates, "fresh_keys": {"keys": [20, 21], "report_half": fresh}}
    )
    rows = {}
    for line in text.splitlines():
        if line.startswith("| ") and line.split("|")[1].strip().isdigit():
            rows.setdefault(line.split("|")[1].strip(), []).append(line)
    assert "| no |" in rows["2"][0] and "| yes |" in rows["4"][0] and "| no |" in rows["8"][0]
    assert "(reference)" in rows["50"][0]
    assert rows["4"][0].endswith("| 0.980 | 0.700 |")  # the same checkpoint and w at T = 1
    assert rows["2"][1].endswith("| +0.020 (+0.010, +0.030) | 1 of 2 |")  # other keys: the gap key by key


def test_a_candidate_is_scored_through_a_config_and_no_checkpoint_is_written(monkeypatch, tmp_path):
    import jgrounding as jg

    seen = {}

    def fake_sample(key, intent, intensity, num_samples=1, **kwargs):
        seen.update(kwargs)
        raise jg.safety.UnsafeActuationError("stop here: only the settings are checked")

    monkeypatch.setattr(jg, "sample", fake_sample)
    monkeypatch.setattr(ship, "write_atomic", lambda *a: seen.setdefault("written", a))
    assert ship.evaluate(tmp_path / "ck", 0.5, 4, noise_scale=1.2) is None
    assert seen["config"] == jg.SampleConfig(steps=4, guidance=0.5, noise_scale=1.2)
    assert "steps" not in seen and "written" not in seen  # the settings travel as a value, not via meta.json
