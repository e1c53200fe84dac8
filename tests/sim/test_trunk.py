"""The tendon-driven trunk: conventions, rollouts, features, MJX/native agreement."""

import numpy as np
import pytest

from jgrounding import sim


def hold(pulls, steps=150):
    return np.tile(np.asarray(pulls, float), (steps, 1))


def test_model_structure():
    m = sim.load_model()
    assert m.nu == 4 and m.ntendon == 4 and m.njnt == 3 * sim.NUM_SEGMENTS
    assert sim.CONTROL_DT == pytest.approx(1 / 30)


def test_rollout_shapes_and_rest_posture():
    r = sim.rollout(np.zeros((2, 150, 4)))
    assert r.backbone.shape == (2, 150, sim.NUM_SEGMENTS + 1, 3)
    assert r.tip.shape == (2, 150, 3) and r.tendon_length.shape == (2, 150, 4)
    assert r.stable.all() and np.abs(r.tip[:, -1, :2]).max() < 1e-3  # hangs straight down
    assert (r.contact_force == 0).all()


def test_each_tendon_bends_toward_its_side_and_cocontraction_retracts():
    u = np.stack(
        [
            hold([0.6, 0, 0, 0]),
            hold([0, 0.6, 0, 0]),
            hold([0, 0, 0.6, 0]),
            hold([0, 0, 0, 0.6]),
            hold([0.6, 0.6, 0.6, 0.6]),
            hold([0, 0, 0, 0]),
        ]
    )
    tip = sim.rollout(u, contact=False).tip[:, -1]
    assert tip[0, 0] > 0.15 and tip[2, 0] < -0.15  # toward / away from the user (x)
    assert tip[1, 1] > 0.15 and tip[3, 1] < -0.15  # left / right (y)
    assert tip[4, 2] > tip[5, 2] + 0.1 and np.abs(tip[4, :2]).max() < 0.01  # shorter, straight


def test_reaching_the_user_makes_gentle_contact_and_a_jump_is_infeasible():
    ramp = np.clip(np.linspace(0, 1.5, 150), 0, 1)[:, None] * np.array([1.0, 0, 0, 0])
    r = sim.rollout(np.stack([ramp, hold([0.8, 0, 0, 0]), hold([0, 0, 0, 0])]))  # slow approach, step, rest
    assert r.contact_force[0].max() > 0 and r.user_distance[0].min() < 0.03
    assert sim.feasible(r).tolist() == [True, False, True]  # the step hits the user too fast
    margin = sim.feasibility_margin(r)
    assert ((margin >= 0) == sim.feasible(r)).all() and margin[2] == pytest.approx(1.0)  # rest: all slack


def test_auto_engine_is_native_on_cpu():
    import jax

    if jax.default_backend() == "cpu":
        assert sim.resolve_engine("auto") == "native"
    else:
        assert sim.resolve_engine("auto") in ("mjx", "mjx-warp")
    assert sim.resolve_engine("mjx") == "mjx" and sim.resolve_engine("mjx-warp") == "mjx-warp"


def test_mjx_warp_is_refused_with_its_reason_where_warp_cannot_run(tmp_path):
    """Without warp-lang (hidden from the import system in a fresh process), engine "mjx-warp" stops before any
    work with an error that says why and names the engines that can run."""
    import subprocess
    import sys

    code = (
        "import sys; sys.modules['warp'] = None\n"
        "import numpy as np\nfrom jgrounding import sim\n"
        "try:\n    sim.rollout(np.zeros((2, 150, 4)), engine='mjx-warp')\n"
        "except RuntimeError as e:\n    print(e)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert 'engine "mjx-warp" cannot run here: warp-lang is not installed' in out.stdout, out.stderr[-2000:]
    assert "valid engines here: auto, native, mjx" in out.stdout


def test_probe_commands_are_valid_and_varied():
    from jgrounding.sim import engines

    u = engines.probe_commands(8, 150)
    assert u.shape == (8, 150, 4) and u.min() >= 0 and u.max() <= 1
    assert np.abs(u[0] - u[1]).max() > 0.1  # the batch is not one trajectory repeated


def test_features_cover_the_shape_vocabulary():
    f = sim.features(sim.rollout(np.stack([hold([0.5, 0, 0, 0]), hold([0, 0, 0.5, 0])])))
    for k in (
        "reach_toward_user",
        "curvature_max",
        "lateral_excursion",
        "vertical_excursion",
        "min_user_distance",
        "peak_tip_speed",
    ):
        assert f[k].shape == (2,)
    assert f["reach_toward_user"][0] > 0.1 > f["reach_toward_user"][1]
    assert f["retreat_from_user"][1] > 0.1


@pytest.mark.parametrize(
    "bad, match",
    [
        (np.zeros((150, 3)), "shape"),
        (np.full((150, 4), 1.5), r"\[0, 1\]"),
        (np.full((150, 4), np.nan), "NaN"),
    ],
)
def test_bad_commands_raise(bad, match):
    with pytest.raises(ValueError, match=match):
        sim.rollout(bad)


def test_contact_pruning_is_exact():
    """Only the distal segments have contact pairs with the user: the others can never reach it."""
    import itertools

    from jgrounding.sim import mjcf as tm

    levels = [np.array(c, float) for c in itertools.product([0, 0.5, 1.0], repeat=4)]
    ramp = np.clip(np.linspace(0, 1.5, 150), 0, 1)[:, None]
    u = np.stack([hold(c) for c in levels] + [ramp * c for c in levels])
    bb = sim.rollout(u, contact=False).backbone  # no contact: the deepest reach toward the user
    first = tm.NUM_SEGMENTS - tm.CONTACT_SEGMENTS  # segments first.. have pairs; points 0..first bound the rest
    a, b = np.array([tm.USER_TORSO_X, 0, tm.USER_TORSO_Z[0]]), np.array([tm.USER_TORSO_X, 0, tm.USER_TORSO_Z[1]])
    torso = sim.segment_distance(bb[:, :, : first + 1], a, b) - tm.USER_TORSO_RADIUS - tm.BASE_RADIUS
    assert torso.min() > 0.01
    head = np.linalg.norm(bb - np.array(tm.USER_HEAD[:3]), axis=-1) - tm.USER_HEAD[3] - tm.BASE_RADIUS
    assert head.min() > 0.1
    assert sim.load_model().npair == tm.CONTACT_SEGMENTS and sim.load_model(None, False).npair == 0


def test_unknown_engine():
    with pytest.raises(ValueError, match="native, mjx, mjx-warp"):
        sim.rollout(np.zeros((150, 4)), engine="bullet")


@pytest.mark.slow
@pytest.mark.parametrize("contact", [True, False], ids=["with_user_contact", "without_user_contact"])
def test_mjx_agrees_with_native(contact):
    from jgrounding.sim import mjx as trunk_mjx

    trunk_mjx.enable_compilation_cache()
    t = np.linspace(0, 1, 150)[:, None]
    reach = np.clip(1.5 * t, 0, 1)
    u = np.stack(
        [
            np.hstack([reach, 0 * t, 0 * t, 0.1 * t]),  # reaches the user and presses on it
            np.hstack([0 * t, 0.5 + 0.4 * np.sin(6 * t), 0.4 * t, 0 * t]),
        ]
    )  # swings away, no contact
    a, b = sim.rollout(u, engine="mjx", contact=contact), sim.rollout(u, engine="native", contact=contact)
    if contact:  # 64 trunks: on the CPU they run as chunks of CPU_MAX_CHUNK (a batch of 64 would deadlock XLA:CPU)
        big = np.tile(u, (32, 1, 1))
        assert np.abs(sim.rollout(big, engine="mjx").tip[-2:] - a.tip).max() < 1e-5
    err = np.linalg.norm(a.tip - b.tip, axis=-1)
    assert err[:, 29].max() < 1e-3  # 1 mm after 1 s
    assert err.max() < 5e-3  # 5 mm over the whole 5 s
    if contact:
        assert b.contact_force[0].max() > 0.05 and b.contact_force[1].max() == 0  # the test does touch
        np.testing.assert_allclose(a.contact_force.max(1), b.contact_force.max(1), rtol=0.1, atol=0.02)
    else:
        assert (a.contact_force == 0).all() and (b.contact_force == 0).all()
        assert b.user_distance[0].min() < 0  # without contact geometry the trunk passes into the user


@pytest.mark.slow
def test_mjx_warp_agrees_with_native_on_the_cpu():
    """The Warp engine is plumbed through jg.sim.rollout: on the CPU (Warp's LLVM backend) it gives native MuJoCo's
    rollout, sensors included, to float32 precision, for a batch that is not a chunk size (padding)."""
    from jgrounding.sim import engines

    u = engines.probe_commands(3, 150)
    u[0] = np.clip(np.linspace(0, 1.5, 150), 0, 1)[:, None] * np.array([1.0, 0, 0, 0])  # presses on the user
    a, b = sim.rollout(u, engine="mjx-warp"), sim.rollout(u, engine="native")
    assert b.contact_force[0].max() > 0.05
    err = np.linalg.norm(a.backbone - b.backbone, axis=-1)
    assert err.max() < 1e-3  # 1 mm over the whole 5 s (float32 against float64; MJX's JAX engine: 5 mm)
    np.testing.assert_allclose(a.tendon_length, b.tendon_length, atol=5e-4)
    np.testing.assert_allclose(a.contact_force, b.contact_force, atol=0.02, rtol=0.05)
    assert sim.feasible(a).tolist() == sim.feasible(b).tolist()


def test_engine_choice_measures_each_engine():
    """The measurement behind engine "auto" on an accelerator times every engine it is given on the same batch."""
    from jgrounding.sim import engines

    rates = engines.measure(("native",), batch=4, steps=30)
    assert set(rates) == {"native"} and rates["native"] > 0
