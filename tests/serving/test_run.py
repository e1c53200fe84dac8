"""Running the server (jgrounding/serving/run.py and ``python -m jgrounding.serve``): the bind check, a server
in a background thread, and the command's refusals of bad options (before any model is loaded)."""

from __future__ import annotations

import pytest

from jgrounding import serve
from jgrounding.serving import run


def test_bind():
    with pytest.raises(ValueError, match="--token"):
        run.check_bind("0.0.0.0", None)
    run.check_bind("0.0.0.0", "secret")
    run.check_bind("127.0.0.1", None)
    assert run.is_loopback("localhost") and run.is_loopback("127.0.0.1") and run.is_loopback("::1")
    assert not run.is_loopback("0.0.0.0") and not run.is_loopback("example.org")


def test_running_listens_on_a_free_loopback_port(running):
    assert running.host == "127.0.0.1" and running.port > 0
    assert running.url == f"ws://127.0.0.1:{running.port}/ws"
    assert running.http == f"http://127.0.0.1:{running.port}/"


@pytest.mark.parametrize(
    "argv, words",
    [
        (["--max-text", "0"], "--max-text"),
        (["--max-samples", "5000"], "--max-samples"),
        (["--burst", "0"], "--burst"),
        (["--rate", "0"], "--rate"),
        (["--stall", "0.01"], "--stall"),
        (["--port", "70000"], "--port"),
        (["--host", "0.0.0.0"], "--token"),
    ],
)
def test_serve_refuses_bad_options_with_exit_2(argv, words, capsys, monkeypatch):
    monkeypatch.delenv("JGROUNDING_TOKEN", raising=False)
    assert serve.main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and words in err
