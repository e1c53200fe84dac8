"""A fitted trunk reaches every part that simulates: rollouts, screening, the physics columns, the render, the
sampler's screening (with a warning naming both trunks), the CLI, the server and the configuration."""

import warnings

import jax
import numpy as np
import pytest

from jgrounding import config, sim
from jgrounding.evaluation import physics
from jgrounding.library import screening
from jgrounding.sim import mjcf as tm

STRONG = tm.TrunkParams(tendon_force=20.0, stiffness_tip=0.4)  # a lab's trunk: visibly different motion


@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
    path = tmp_path_factory.mktemp("trunk") / "my_trunk.xml"
    path.write_text(tm.build_xml(params=STRONG, exact=True))
    return str(path)


def ramp(pulls):
    return np.clip(np.linspace(0, 1.2, 150), 0, 1)[:, None] * np.asarray(pulls, float)


def test_rollout_and_margins_simulate_the_given_trunk(fitted):
    u = np.stack([ramp([0.6, 0, 0, 0]), ramp([0, 0.5, 0, 0.2])])
    shipped, mine = sim.rollout(u), sim.rollout(u, trunk=fitted)
    assert np.abs(mine.tip - shipped.tip).max() > 0.02  # stronger pull, softer tip: the motion differs
    again = sim.rollout(u, trunk=tm.DEFAULT_PATH)  # the shipped file by path is the shipped trunk
    np.testing.assert_array_equal(again.backbone, shipped.backbone)
    np.testing.assert_array_equal(sim.margins(u, trunk=fitted), sim.feasibility_margin(mine))
    with pytest.raises(FileNotFoundError, match="trunk .* not found"):
        sim.rollout(u, trunk="missing_trunk.xml")


def test_a_trunk_of_another_layout_and_a_delay_on_mjx_are_refused(tmp_path):
    other = tmp_path / "eight.xml"
    other.write_text(tm.build_xml(params=tm.TrunkParams(segments=8)))
    with pytest.raises(ValueError, match="8 segments"):
        sim.rollout(np.zeros((150, 4)), trunk=str(other))
    delayed = tmp_path / "delayed.xml"
    delayed.write_text(tm.build_xml(params=tm.TrunkParams(delay=0.03), exact=True))
    assert sim.resolve_engine("auto", str(delayed)) == "native"
    with pytest.raises(ValueError, match="command delay"):
        sim.rollout(np.zeros((150, 4)), engine="mjx", trunk=str(delayed))


def test_screening_and_the_physics_columns_use_the_trunk(fitted):
    u = np.stack([ramp([0.6, 0, 0, 0]), ramp([0, 0, 0.7, 0])]).astype(np.float32)
    checks = screening.screen(u, u, np.zeros(2, int), trunk=fitted)
    np.testing.assert_array_equal(checks["feasible"], sim.feasible(sim.rollout(u, trunk=fitted)))
    ref = sim.rollout(u, trunk=fitted).backbone
    mine = physics.simulate_samples(u[:, None], ref, 0.01, trunk=fitted)
    shipped = physics.simulate_samples(u[:, None], ref, 0.01)
    assert mine["shape_rms"].max() == 0.0 and shipped["shape_rms"].min() > 0.005


def test_the_render_shows_the_trunk(fitted):
    from jgrounding.sim import render

    u = ramp([0.6, 0, 0, 0])
    a, _ = render.frames(u, [149], backend="matplotlib")
    b, _ = render.frames(u, [149], backend="matplotlib", trunk=fitted)
    assert a[0].shape == b[0].shape and np.abs(a[0].astype(int) - b[0].astype(int)).max() > 0


def test_config_takes_the_trunk_by_set(fitted):
    cfg = config.get("quick", [f"physics.trunk={fitted}"])
    assert cfg.physics.trunk == fitted and config.from_dict(config.to_dict(cfg)) == cfg
    assert config.get("quick", ["physics.trunk=none"]).physics.trunk is None


def test_mismatch_is_said_naming_both_trunks(fitted):
    assert sim.trunk_mismatch(None, None) is None
    assert sim.trunk_mismatch(sim.trunk_identity(fitted), fitted) is None
    why = sim.trunk_mismatch(None, fitted)
    assert "the shipped trunk" in why and fitted in why


@pytest.mark.slow
def test_screened_sampling_the_cli_and_the_server_pass_the_trunk(fitted, tmp_path, capsys):
    import jgrounding as jg
    from jgrounding import serving
    from jgrounding.apps import cli

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        u = jg.sample(jax.random.key(0), "greeting", "moderate", 2, screen=True, trunk=fitted)
    assert u.shape == (2, 150, 4)
    assert any("the shipped trunk" in str(w.message) and fitted in str(w.message) for w in caught)
    policy = serving.Policy(None, warm=False, trunk=fitted)
    np.testing.assert_array_equal(policy.rollout(u[0]), sim.rollout(u[:1], trunk=fitted).backbone[0].astype("f4"))
    out = tmp_path / "out"
    rc = cli.main(["--intent", "greeting", "--intensity", "moderate", "--screen", "--trunk", fitted, "--out", str(out)])
    assert rc == 0 and (out / "posture.png").exists()
    assert "warning: checkpoint" in capsys.readouterr().out  # the trunk mismatch, said by the CLI
    with pytest.raises(SystemExit):
        cli.main(["--intent", "greeting", "--intensity", "moderate", "--trunk", str(tmp_path / "no.xml")])
    assert "--trunk" in capsys.readouterr().err
