"""The trunk from its description: every named parameter of SPEC section 9, the shipped file by default."""

import mujoco
import numpy as np
import pytest

from jgrounding.sim import model as tm


def test_defaults_reproduce_the_shipped_trunk_byte_for_byte(tmp_path):
    shipped = tm.DEFAULT_PATH.read_bytes()
    assert tm.build_xml().encode() == shipped
    toml = tmp_path / "trunk.toml"
    out = tmp_path / "trunk.xml"
    assert tm.main(["--out", str(tmp_path / "a.xml"), "--write-config", str(toml)]) == 0
    assert tm.main(["--config", str(toml), "--out", str(out)]) == 0
    assert out.read_bytes() == shipped and (tmp_path / "a.xml").read_bytes() == shipped
    assert tm.load_config(toml) == tm.TrunkParams()


def test_every_parameter_reaches_the_model(tmp_path):
    p = tm.TrunkParams(
        segments=8, length=0.6, stiffness_root=5.0, stiffness_tip=0.4, damping_root=0.2, damping_tip=0.05,
        tendon_force=11.0, slide_stiffness=3000.0, slide_damping=6.0, density=400.0, routing_root=0.03,
        delay=0.04,
    )  # fmt: skip
    (tmp_path / "t.toml").write_text(tm.to_toml(p))
    assert tm.load_config(tmp_path / "t.toml") == p
    m = mujoco.MjModel.from_xml_string(tm.build_xml(params=p, exact=True))
    assert m.nbody == 8 + 2  # world, user, 8 segments
    assert m.jnt_stiffness[m.joint("bx0").id] == 5.0 and m.jnt_stiffness[m.joint("bx7").id] == pytest.approx(0.4)
    assert m.dof_damping[m.joint("by7").dofadr[0]] == pytest.approx(0.05)
    assert m.jnt_stiffness[m.joint("sl3").id] == 3000.0 and m.dof_damping[m.joint("sl3").dofadr[0]] == 6.0
    assert m.actuator_gear[0, 0] == -11.0 and np.allclose(m.actuator_delay, 0.04)
    tip = m.site("tip")
    assert sum(tm.segment_lengths(8, p)) == pytest.approx(0.6) and tip is not None
    heavier = mujoco.MjModel.from_xml_string(tm.build_xml(params=p.replace(density=800.0)))
    assert heavier.body_mass[m.body("seg0").id] == pytest.approx(2 * m.body_mass[m.body("seg0").id])


def test_bad_descriptions_are_refused_naming_the_valid(tmp_path):
    (tmp_path / "bad.toml").write_text("stifness_root = 3.0\n")
    with pytest.raises(ValueError, match="unknown trunk parameters.*stiffness_root"):
        tm.load_config(tmp_path / "bad.toml")
    with pytest.raises(ValueError, match="density must be a finite number > 0"):
        tm.TrunkParams(density=-1.0)
    with pytest.raises(ValueError, match="segments"):
        tm.TrunkParams(segments=1)
    with pytest.raises(FileNotFoundError):
        tm.load_config(tmp_path / "missing.toml")
