"""Calibration with mujoco.sysid: identifiability on our own trunk, the split, the report, and clear failures."""

import json

import numpy as np
import pytest

from jgrounding import load_library
from jgrounding.sim import calibration as cal
from jgrounding.sim import mjcf as tm
from jgrounding.sim.__main__ import main
from jgrounding.sim.recordings import write_recordings
from jgrounding.sim.synthetic import synthesize

MARKERS = (("mid", 0.35), ("tip", 0.70))
# Every default parameter moved 6-15 % inside its bounds: the trunk the recordings come from.
PERTURBED = tm.TrunkParams(
    stiffness_root=8.0,
    stiffness_tip=0.45,
    damping_root=0.4,
    damping_tip=0.033,
    tendon_force=15.0,
    slide_stiffness=2700.0,
    density=380.0,
    delay=0.03,
)


def recordings(params, count, noise=0.0):
    u = load_library().train.u[:: 192 // count][:count]
    return synthesize(u, params, [m for m, _ in MARKERS], [s for _, s in MARKERS], noise=noise)


@pytest.mark.slow
def test_identifiability_recovers_each_parameter_within_5_percent_and_the_backbone_within_1_mm():
    result = cal.calibrate(recordings(PERTURBED, 8), settings=cal.Settings(validation=0.25), log=lambda s: None)
    for name in cal.FIT_PARAMETERS:
        assert getattr(result.fitted, name) == pytest.approx(getattr(PERTURBED, name), rel=0.05), name
    assert result.rms["fit"]["after"][0] < 0.001 and result.rms["validation"]["after"][0] < 0.001
    assert result.rms["fit"]["before"][0] > 0.005  # the start was off: the fit did the work


def test_two_parameters_are_recovered_and_the_cli_writes_the_trunk_with_its_provenance(tmp_path):
    lab = tm.TrunkParams(tendon_force=16.0, stiffness_tip=0.42)
    folder = write_recordings(tmp_path / "recs", recordings(lab, 3), marker_units="mm")
    out = tmp_path / "fitted" / "my_trunk.xml"
    rc = main(["calibrate", str(folder), "--out", str(out), "--fit", "tendon_force,stiffness_tip", "--no-html"])
    assert rc == 0
    prov = json.loads(out.with_suffix(".json").read_text())
    assert prov["parameters"]["tendon_force"]["value"] == pytest.approx(16.0, rel=0.01)
    assert prov["parameters"]["stiffness_tip"]["value"] == pytest.approx(0.42, rel=0.01)
    assert len(prov["recordings"]["sha256"]) == 64 and prov["mujoco"]
    assert len(prov["recordings"]["fit"]) == 2 and len(prov["recordings"]["validation"]) == 1
    assert "Fitted by python -m jgrounding.sim calibrate" in out.read_text()
    report = (tmp_path / "fitted" / "my_trunk.report" / "report.md").read_text()
    assert "| tendon_force |" in report and "| validation |" in report
    assert (tmp_path / "fitted" / "my_trunk.report" / "paths.png").stat().st_size > 10_000
    import mujoco

    m = mujoco.MjModel.from_xml_path(str(out))
    assert m.actuator_gear[0, 0] == pytest.approx(-16.0, rel=0.01)


def test_split_is_seeded_and_disjoint():
    recs = recordings(tm.TrunkParams(), 4)
    fit, val = cal.split(recs, 0.25, 0)
    assert len(val) == 1 and {r.name for r in fit} | {r.name for r in val} == {r.name for r in recs}
    assert [r.name for r in cal.split(recs, 0.25, 0)[1]] == [r.name for r in val]
    assert cal.split(recs[:1], 0.25, 0)[1] == []


def test_bad_input_is_refused_and_nothing_is_written(tmp_path):
    recs = recordings(tm.TrunkParams(), 2)
    with pytest.raises(cal.CalibrationError, match="no recordings"):
        cal.calibrate([])
    no_markers = [r.__class__(**{**r.__dict__, "markers": np.zeros((len(r.t), 0, 3))}) for r in recs]
    with pytest.raises(cal.CalibrationError, match="no motion-capture markers"):
        cal.calibrate(no_markers)
    with pytest.raises(cal.CalibrationError, match="unknown parameter"):
        cal.Settings(bounds=(("stifness", 1.0, 2.0),))
    with pytest.raises(cal.CalibrationError, match="must be distinct names of"):
        cal.Settings(parameters=("mass",))
    with pytest.raises(cal.CalibrationError, match="NAME=LOW,HIGH"):
        cal.parse_bound("tendon_force=5")
    out = tmp_path / "t.xml"
    assert main(["calibrate", str(tmp_path / "missing"), "--out", str(out)]) == 2
    assert not list(tmp_path.iterdir())


def test_an_unstable_model_and_no_convergence_are_errors(tmp_path):
    recs = recordings(tm.TrunkParams(slide_stiffness=2600.0), 2)
    unstable = cal.Settings(parameters=("slide_stiffness",), bounds=(("slide_stiffness", 1e7, 1e9),), validation=0)
    with pytest.raises(cal.CalibrationError, match="unstable"):
        cal.calibrate(recs, settings=unstable, log=lambda s: None)
    budget = cal.Settings(parameters=("tendon_force", "stiffness_root"), max_iters=1, validation=0)
    with pytest.raises(cal.CalibrationError, match="no convergence within 1 iterations"):
        cal.calibrate(recordings(tm.TrunkParams(tendon_force=20.0), 2), settings=budget, log=lambda s: None)
