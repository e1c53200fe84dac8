"""The library (v3 and v4) looks like recordings of a real trunk: it starts from rest, returns or holds, and each intent's
simulated motion shows its description (SPEC §2-3), checked as kinematic signatures over the whole library."""

import numpy as np
import pytest

import jgrounding as jg
from jgrounding import sim
from jgrounding.library import primitives
from jgrounding.vocabulary import INTENTS


@pytest.fixture(scope="module")
def recorded():
    lib = jg.load_library()
    u = np.concatenate([lib.train.u, lib.heldout.u, lib.evaluation.u])
    m = np.concatenate([lib.train.intent, lib.heldout.intent, lib.evaluation.intent])
    z = np.concatenate([lib.train.intensity, lib.heldout.intensity, lib.evaluation.intensity])
    return u, m, z, sim.features(sim.rollout(u, engine="native"))


def _of(name, recorded):
    u, m, z, f = recorded
    sel = m == INTENTS.index(name)
    return {k: v[sel] for k, v in f.items()}, z[sel]


def test_every_realization_starts_from_rest_and_returns_or_holds(recorded):
    u, m, _, _ = recorded
    assert np.all(u[:, 0] == primitives.REST)
    returns = primitives.RETURNS_MASK[m]
    assert returns.any() and np.all(u[returns, -1] == primitives.REST)
    assert np.abs(u[~returns, -1] - u[~returns, -2]).max() < 0.03  # the others hold their last pose


def test_greeting_rises_toward_the_user_and_waves(recorded):
    f, _ = _of("greeting", recorded)
    assert np.all(f["rise"] > 0.0) and np.all(f["lateral_reversals"] >= 1)
    assert np.mean(f["reach_toward_user"]) > 0.0


def test_withdrawal_ends_farther_from_the_user(recorded):
    f, _ = _of("withdrawal", recorded)
    assert np.all(f["final_retreat"] > 0.0) and np.all(f["reach_toward_user"] < 0.05)


def test_nodding_is_sagittal_and_refusing_lateral(recorded):
    nod, _ = _of("nodding", recorded)
    shake, _ = _of("refusing", recorded)
    assert np.all(nod["sagittal_excursion"] > nod["lateral_excursion"]) and np.all(nod["vertical_reversals"] >= 1)
    assert np.all(shake["lateral_excursion"] > 0.8 * shake["sagittal_excursion"])
    assert np.median(shake["lateral_excursion"] / shake["sagittal_excursion"]) > 2 * np.median(
        nod["lateral_excursion"] / nod["sagittal_excursion"]
    )


def test_comforting_and_embracing_reach_the_user_withdrawal_and_coiling_do_not(recorded):
    for name in ("comforting", "embracing", "offering"):
        f, z = _of(name, recorded)
        assert np.all(f["min_user_distance"][z == 3] < 0.15), name
    for name in ("withdrawal", "coiling"):
        f, _ = _of(name, recorded)
        assert np.all(f["reach_toward_user"] < 0.08), name


def test_playful_swing_and_celebrating_swing_side_to_side(recorded):
    for name in ("playful_swing", "celebrating", "curiosity"):
        f, _ = _of(name, recorded)
        assert np.all(f["lateral_reversals"] >= 1), name
    f, z = _of("celebrating", recorded)
    assert np.mean(f["rise"][z == 3]) > np.mean(f["rise"][z == 0])


def test_intensity_grows_the_motion(recorded):
    # Intensity is reach and tempo (SPEC §2): the tip's path grows from subtle to emphatic for every intent but
    # resting (minimal motion at every intensity). Libraries v4 and v5's subtle gestures may pull as hard as emphatic ones
    # (later and slower, issue #38), so the mean pull is no longer the measure; v3 also asserted it.
    u, m, z, f = recorded
    path = f["lateral_excursion"] + f["sagittal_excursion"] + f["vertical_excursion"]
    for k, name in enumerate(INTENTS):
        if name == "resting":
            continue
        sel = m == k
        assert path[sel & (z == 3)].mean() > path[sel & (z == 0)].mean(), name
        assert f["peak_tip_speed"][sel & (z == 3)].mean() > f["peak_tip_speed"][sel & (z == 0)].mean(), name
