"""Act when asked, hold with a reason, the same everywhere: the CLI, the interactive loop, the server's replies, its
stream, the client and the page make the same decision for the same text and show the same reason first, the
tuple only after it as "nearest"."""

from __future__ import annotations

import io
import json
import re
from pathlib import Path

import pytest

from jgrounding.policy.respond import Responder

ACTS = ("wave back enthusiastically!", "Give a small nod to show you are listening.")
HOLDS = ("please stay still, the nurse is checking you", "Grandpa to his grandson: 'Come here and give me a big hug!'")
TEXTS = (*ACTS, *HOLDS)


@pytest.fixture(scope="module")
def decisions():
    responder = Responder()
    return {text: responder.decide(text) for text in TEXTS}


def test_the_responder_acts_on_the_orders_and_holds_the_rest(decisions):
    assert [decisions[t].hold for t in TEXTS] == [False, False, True, True]
    assert [(decisions[t].intent) for t in ACTS] == ["greeting", "nodding"]
    nurse = decisions[HOLDS[0]]
    assert nurse.message().startswith("holding still: the text orders the trunk to keep still")
    assert nurse.nearest.startswith("nearest: (") and decisions[ACTS[0]].nearest is None


def test_the_interactive_loop_acts_on_orders_and_holds_without_showing_a_tuple(decisions, tmp_path):
    from jgrounding.apps import interact

    out = io.StringIO()
    assert interact.main(["--out", str(tmp_path)], io.StringIO("\n".join(TEXTS) + "\n:history\n:quit\n"), out) == 0
    turns = out.getvalue().split(interact.PROMPT)[1:]
    assert "-> (greeting, " in turns[0] and "-> (nodding, " in turns[1]
    for text, turn in zip(HOLDS, turns[2:]):
        d = decisions[text]
        assert turn.lstrip().startswith(f"holding still: {d.reason};"), turn
        assert "-> (" not in turn  # no tuple in large type: only the nearest one, after the hold, in parentheses
        lines = turn.strip().splitlines()
        assert lines[-1].strip() == f"({d.nearest})"
    assert turns[4].strip().startswith("greeting/") and "nodding/" in turns[4]  # :history: the two that moved
    assert (tmp_path / "turn002.png").exists() and not (tmp_path / "turn003.png").exists()


def test_the_cli_shows_the_hold_first_and_the_tuple_as_nearest(decisions, tmp_path, capsys):
    from jgrounding.apps import cli

    for i, text in enumerate(TEXTS):
        out = tmp_path / str(i)
        assert cli.main([text, "--samples", "1", "--no-render", "--jsonl", "--out", str(out)]) == 0
        events = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
        d = decisions[text]
        if d.hold:
            assert events[0] == {"event": "holding", "reason": d.reason, "hold_still": True}
            assert events[1]["event"] == "tuple" and events[1]["nearest"] is True
        else:
            assert events[0]["event"] == "tuple" and events[0]["intent"] == d.intent and not events[0]["nearest"]
            assert not any(e.get("hold_still") for e in events)
    assert cli.main([HOLDS[0], "--samples", "1", "--no-render", "--out", str(tmp_path / "plain")]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith(f"holding still: {decisions[HOLDS[0]].reason};")
    assert lines[1].strip().startswith(decisions[HOLDS[0]].nearest)


def test_the_server_its_stream_and_the_client_show_the_same_reason_first(decisions):
    from jgrounding import client as jc
    from jgrounding import serving

    run = serving.Running(serving.Server(serving.Policy(None, warm=False)))
    try:
        c = jc.Client(run.url)
        for text in TEXTS:
            d = decisions[text]
            ground = c.request({"type": "ground", "text": text})
            sample = c.sample(text, steps=2)
            for reply in (ground, sample):  # after the envelope (type, id, ok): the hold and its message first
                assert [k for k in reply if k not in ("type", "id", "ok")][:2] == ["hold_still", "message"]
            for reply in (ground, sample):
                assert reply["hold_still"] == d.hold and reply["message"] == d.message()
                assert reply["grounding"]["nearest"] == d.nearest
                assert (reply["grounding"]["intent"], reply["grounding"]["reason"]) == (d.intent, d.reason)
            shown = jc.shown(sample).splitlines()
            if d.hold:
                assert shown == [d.message(), f"  ({d.nearest})"]
            else:
                assert shown[0].startswith(f"grounding: ({d.intent}, ") and "acting on it" in shown[0]
        stream = c.stream(steps=2)
        for text in TEXTS:
            stream.respond(text)
        for i, _ in enumerate(stream):
            if len(stream.responses) == len(TEXTS) or i > 900:
                break
        assert [r["hold_still"] for r in stream.responses] == [decisions[t].hold for t in TEXTS]
        for text, r in zip(TEXTS, stream.responses):
            d = decisions[text]
            assert (r["message"] or "").startswith(f"holding still: {d.reason};" if d.hold else "")
            assert r["grounding"]["nearest"] == d.nearest
        stream.stop()
    finally:
        run.stop()


def test_the_page_shows_the_servers_message_first_and_the_tuple_only_as_nearest():
    """The page renders what the server replied (checked above); the browser test (tests/serving/test_page.py)
    types a held text. Here: the page's one renderer puts the reply's ``message`` in the status line above the
    tuple, blanks the tuple's large type for a held text and puts ``nearest`` in small print."""
    page = (Path(__file__).resolve().parents[2] / "jgrounding" / "apps" / "static" / "index.html").read_text()
    body = page[page.index("function showGrounding(r) {") : page.index("function drawTendons")]
    assert 'hold ? "-" : g.intent' in body and 'hold ? "-" : g.intensity' in body
    assert "r.message" in body and '$("nearest").textContent = hold ? (g.nearest' in body
    assert page.index('id="status"') < page.index('id="intent"') < page.index('id="nearest"')
    assert re.search(r'<small[^>]*id="nearest"', page)
    assert page.count("showGrounding(") == 4 and "showGrounding(r.grounding" not in page
