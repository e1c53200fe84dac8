"""Own models in the apps (issue #26): the docs' example model driven from text by the CLI and the
interactive loop; command streams in the lab's names and units; the loop's prompt, help and clean exits."""

import io
import json
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from jgrounding import safety
from jgrounding.apps import cli, export, interact, own

ROOT = Path(__file__).resolve().parents[2]
LIMITS_MM = [(1.5, 13.5), (2.0, 14.0), (1.0, 13.0), (2.5, 14.5)]  # the example folder's manifest.json
CHANNELS = ["pull_0_mm", "pull_1_mm", "pull_2_mm", "pull_3_mm"]


@pytest.fixture(scope="module")
def own_checkpoint(own_model):
    return own_model[1]  # built once per session (tests/conftest.py)


def test_import_info_comes_from_the_import(own_checkpoint):
    info = own.import_info(own_checkpoint)
    assert info["channels"] == CHANNELS and info["limits"] == LIMITS_MM
    assert own.import_info(None) is None  # the shipped model: the built-in trunk's layout


def test_grounding_is_restricted_to_the_checkpoint_tuples(own_checkpoint):
    from jgrounding.semantics.types import Grounding

    def g(intent, intensity):
        scores = tuple(0.9 if i == "greeting" else 0.01 for i in own.INTENTS)
        return Grounding(intent, intensity, 0.95, "embedded", True, "", scores)

    same, note = own.restrict(g("nodding", "emphatic"), own_checkpoint)
    assert (same.intent, same.intensity, same.confident, note) == ("nodding", "emphatic", True, None)
    near, note = own.restrict(g("nodding", "subtle"), own_checkpoint)  # the intent is learned, the intensity not
    assert (near.intent, near.intensity, near.confident) == ("nodding", "moderate", True)
    assert "learned nodding only at moderate, emphatic: using the nearest, (nodding, moderate)" in note
    other, note = own.restrict(g("comforting", "pronounced"), own_checkpoint)  # an intent it never learned
    assert (other.intent, other.intensity, other.confident) == ("greeting", "moderate", False)
    assert "asked for (comforting, pronounced), outside the tuples checkpoint" in note
    assert "greeting/moderate, greeting/emphatic, nodding/moderate, nodding/emphatic" in note
    assert own.restrict(g("comforting", "pronounced"), None)[1] is None  # the shipped model has every tuple


def test_cli_text_with_own_checkpoint(own_checkpoint, tmp_path):
    """``python -m jgrounding TEXT --checkpoint OWN`` as a user types it: the tuple it was not trained on is
    named, the trunk holds still, and a learned one is driven, exported in the lab's units and names."""
    env = {**os.environ, "JAX_PLATFORMS": "cpu", "PYTHONPATH": str(ROOT)}
    out = tmp_path / "sad"
    p = subprocess.run(
        [sys.executable, "-m", "jgrounding", "User seems sad; respond calmly", "--checkpoint", str(own_checkpoint)]
        + ["--out", str(out), "--no-render"],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert p.returncode == 0, p.stderr
    assert "outside the tuples checkpoint" in p.stdout and "holding still" in p.stdout
    header, u = export.read_command_stream_csv(out / "commands.csv")
    assert header["hold_still"] and header["channels"] == CHANNELS and not u.any()

    out = tmp_path / "nod"
    argv = ["Nod enthusiastically: yes, yes!", "--checkpoint", str(own_checkpoint), "--out", str(out)]
    assert cli.main(argv + ["--no-render", "--units", "lab", "--samples", "2"]) == 0
    header, lab = export.read_command_stream_csv(out / "commands.csv")
    assert header["intent"] == "nodding" and header["channels"] == CHANNELS
    assert header["limits"] == [list(p) for p in LIMITS_MM] and "lab's own units" in header["units"]
    u = np.load(out / "samples.npy")[0]
    np.testing.assert_allclose(lab, export.to_lab_units(u, LIMITS_MM), atol=2e-5)
    assert (lab >= np.array(LIMITS_MM)[:, 0] - 1e-6).all() and (lab <= np.array(LIMITS_MM)[:, 1] + 1e-6).all()
    doc = json.loads((out / "commands.json").read_text())
    np.testing.assert_allclose(doc["commands"], lab, atol=2e-5)


def test_cli_lab_units_need_an_imported_library(tmp_path, capsys):
    assert cli.main(["--intent", "nodding", "--intensity", "subtle", "--units", "lab", "--out", str(tmp_path)]) == 1
    assert "--units lab needs a checkpoint trained on an imported library" in capsys.readouterr().err


def test_intent_without_intensity_says_the_default(tmp_path, capsys):
    assert cli.main(["--intent", "nodding", "--samples", "1", "--no-render", "--out", str(tmp_path)]) == 0
    printed = capsys.readouterr().out
    assert "tuple: (nodding, moderate) [intent given; intensity not given: the default 'moderate']" in printed
    assert "[given]" not in printed


def test_hold_still_plot_is_not_titled_like_a_motion(tmp_path, monkeypatch, capsys):
    from jgrounding.apps import plotting

    titles = []
    real = plotting.tendon_figure
    monkeypatch.setattr(plotting, "tendon_figure", lambda u, p, **kw: titles.append(kw["title"]) or real(u, p, **kw))
    assert cli.main(["zzqx blorf", "--samples", "1", "--no-render", "--out", str(tmp_path)]) == 0
    assert "hold" in capsys.readouterr().out
    # a held text shows the tuple only as the nearest one, after the hold (the title named it "grounded" before)
    assert "holding still (nearest (" in titles[0] and titles[0].endswith("not acted on)")


class _Interrupted(io.StringIO):
    """stdin whose user presses Ctrl-C after the given lines."""

    def readline(self, *a):
        line = super().readline(*a)
        if not line:
            raise KeyboardInterrupt
        return line


def test_interact_with_own_checkpoint_prompt_help_and_ctrl_c(own_checkpoint, tmp_path):
    out = io.StringIO()
    said = ":help\nNod enthusiastically: yes, yes!\nUser seems sad; respond calmly\n:force\n"
    code = interact.main(["--checkpoint", str(own_checkpoint), "--out", str(tmp_path)], _Interrupted(said), out)
    text = out.getvalue()
    assert code == 0 and "Traceback" not in text
    assert text.count(interact.PROMPT) == 5  # one per line read, the interrupted one included
    assert ":force     drive the last grounding" in text and "``" not in text and ":data:" not in text
    assert "-> (nodding, emphatic)" in text
    assert "outside the tuples checkpoint" in text and "holding still" in text
    # :force drives the nearest tuple the checkpoint knows, the one the note named (which of its tuples that is
    # depends on the head's scores of tuples far from the text, all near 0).
    nearest = re.search(r"its nearest is (\((?:greeting|nodding), \w+\))", text).group(1)
    assert f"forcing {nearest}" in text
    assert "(interrupted)" in text and "trunk brought back to rest" in text
    stream = np.load(tmp_path / "stream.npy")  # two turns, then the ramp back to rest
    assert stream.shape == (2 * 150 + safety.BLEND_STEPS + 1, 4) and not stream[-1].any()
    steps = np.abs(np.diff(np.concatenate([np.zeros((1, 4)), stream]), axis=0))
    assert steps.max() <= safety.MAX_SLEW + 1e-6


def test_interact_ends_cleanly_at_end_of_input(tmp_path):
    out = io.StringIO()
    assert interact.main(["--out", str(tmp_path), "--backend", "cues"], io.StringIO(""), out) == 0
    assert out.getvalue().endswith("the trunk is at rest; bye\n")
    with pytest.raises(SystemExit):
        interact.main(["--checkpoint", str(tmp_path / "nope")], io.StringIO(""), io.StringIO())


@pytest.mark.parametrize("model", ["shipped", "own"])
def test_cli_and_server_give_the_same_decision_and_trajectory(model, own_checkpoint, tmp_path):
    """One decision path (issue #33): for the same text, key and checkpoint the CLI and the server snap, hold
    or move alike and return the same trajectory, for the built-in model and a lab's model (which knows only
    some tuples: another intensity snaps to the nearest learned one, an unlearned intent holds still)."""
    from jgrounding import serving
    from jgrounding.client import Client

    checkpoint = None if model == "shipped" else own_checkpoint
    run = serving.Running(serving.Server(serving.Policy(checkpoint, warm=False)))
    try:
        client = Client(run.url)
        for i, text in enumerate(["Nod gently, just a little", "User seems sad; respond calmly", "Wave hello!"]):
            out = tmp_path / f"{model}{i}"
            argv = [text, "--seed", "3", "--samples", "2", "--no-render", "--out", str(out)]
            assert cli.main(argv + (["--checkpoint", str(checkpoint)] if checkpoint else [])) == 0
            header, _ = export.read_command_stream_csv(out / "commands.csv")
            reply = client.sample(text, num_samples=2, seed=3)  # the server's defaults, as a robot calls it
            assert reply["hold_still"] == bool(header.get("hold_still")), text
            assert (reply["grounding"]["intent"], reply["grounding"]["intensity"]) == (
                header["intent"],
                header["intensity"],
            ), text
            np.testing.assert_allclose(reply["u"], np.load(out / "samples.npy"), atol=1e-6, err_msg=text)
            if reply["hold_still"]:
                assert reply["message"].startswith("holding still: ")
    finally:
        run.stop()


def test_server_stream_snaps_or_holds_for_a_lab_model(own_checkpoint):
    """A lab's model behind the stream: an unlearned intent holds still with its reason and another intensity
    of a learned intent moves, never an error."""
    from jgrounding import serving
    from jgrounding.client import Client

    run = serving.Running(serving.Server(serving.Policy(own_checkpoint, warm=False)))
    try:
        client = Client(run.url)
        sad = client.request({"type": "ground", "text": "User seems sad; respond calmly"})
        assert sad["hold_still"] and sad["message"].startswith("holding still: ") and not sad["grounding"]["confident"]
        nod = client.sample("Nod gently, just a little", seed=1)
        assert not nod["hold_still"] and nod["grounding"]["intensity"] == "moderate" and nod["grounding"]["note"]
        stream = client.stream(steps=2)
        stream.respond("User seems sad; respond calmly")
        stream.respond("Nod gently, just a little")
        for i, _ in enumerate(stream):
            if len(stream.responses) == 2 or i > 600:
                break
        assert [r["hold_still"] for r in stream.responses] == [True, False]
        stream.stop()
    finally:
        run.stop()
