"""The design file: the paper's defaults, configurable wording, and errors that name the field."""

import pytest

from jgrounding.study import DIMENSIONS, Design, DesignError, load_design


def test_the_default_design_is_the_papers():
    d = Design()
    assert d.conditions == ("av_only", "trunk") and d.dimensions == DIMENSIONS and d.scale == 5
    assert d.needs_model


def test_the_example_design_loads(tmp_path):
    from pathlib import Path

    d = load_design(Path(__file__).resolve().parents[2] / "examples" / "study.toml")
    assert d.conditions == ("av_only", "trunk", "scripted")
    assert len(d.episodes) >= 3 and d.dimensions == DIMENSIONS
    assert any(e.text for e in d.episodes) and any(e.intent for e in d.episodes)


def test_wording_and_labels_are_configurable(tmp_path):
    p = tmp_path / "s.toml"
    p.write_text(
        'name = "mine"\nconditions = ["trunk", "av_only"]\n'
        '[[episodes]]\nintent = "nodding"\nsay = "Yes!"\n'
        "[questionnaire]\nlabels = ['no', 'rather no', 'unsure', 'rather yes', 'yes']\n"
        '[[questionnaire.items]]\ndimension = "naturalness"\nwording = "Natürlich?"\n'
        '[[questionnaire.items]]\ndimension = "warmth"\nwording = "Warm?"\n'
    )
    d = load_design(p)
    assert d.conditions == ("trunk", "av_only") and d.episodes[0].intensity == "moderate"
    assert [q.wording for q in d.questions] == ["Natürlich?", "Warm?"] and d.labels[-1] == "yes"


def test_a_design_survives_the_database_round_trip_with_its_digest(design):
    pytest.importorskip("sqlalchemy", reason="the study's database needs sqlalchemy (requirements.txt pins it)")
    from jgrounding.study.store import Store

    store = Store("sqlite://")
    sid = store.open_session(design)
    assert store.design(sid) == design and store.design(sid).digest() == design.digest()
    assert store.open_session(design) == sid  # the same design resumes its session


@pytest.mark.parametrize(
    "text, match",
    [
        ('conditions = ["av_only", "robot"]', "conditions must be distinct names"),
        ('conditions = ["trunk", "trunk"]', "distinct"),
        ('[[episodes]]\ntext = "hi"\nintent = "greeting"', "either text or intent"),
        ('[[episodes]]\nintent = "dancing"', "intent must be one of"),
        ('[[episodes]]\nintent = "greeting"\nintensity = "huge"', "intensity must be one of"),
        ("stall_s = 0", "stall_s"),
        ("colour = 1", "unknown design fields"),
        ("[questionnaire]\nlabels = ['a', 'b', 'c']", "at least 5 labels"),
        ('[[questionnaire.items]]\ndimension = "Nice One"', "lower_snake_case"),
        ("name = ", "not valid TOML"),
    ],
)
def test_invalid_designs_are_refused_with_the_field(tmp_path, text, match):
    p = tmp_path / "bad.toml"
    p.write_text(text + "\n")
    with pytest.raises(DesignError, match=match):
        load_design(p)
