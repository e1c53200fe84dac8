"""The MLLM backend against a fake OpenAI-compatible server on loopback."""

import json
import threading
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

import pytest

import jgrounding as jg
from jgrounding.semantics import mllm


class FakeServer:
    """Serves the queued replies in order (the last one repeats); bounded, loopback only."""

    def __init__(self, replies):
        self.replies, self.requests = list(replies), []
        outer = self

        class Handler(BaseHTTPRequestHandler):
            def do_POST(self):
                body = json.loads(self.rfile.read(int(self.headers["Content-Length"])))
                outer.requests.append(body)
                reply = outer.replies.pop(0) if len(outer.replies) > 1 else outer.replies[0]
                doc = (
                    reply
                    if isinstance(reply, dict)
                    else {"choices": [{"message": {"role": "assistant", "content": reply}}]}
                )
                data = json.dumps(doc).encode()
                self.send_response(200)
                self.send_header("Content-Type", "application/json")
                self.send_header("Content-Length", str(len(data)))
                self.end_headers()
                self.wfile.write(data)

            def log_message(self, *args):
                pass

        self.httpd = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.url = f"http://127.0.0.1:{self.httpd.server_address[1]}/v1"
        self.thread = threading.Thread(target=self.httpd.serve_forever, daemon=True)

    def __enter__(self):
        self.thread.start()
        return self

    def __exit__(self, *exc):
        self.httpd.shutdown()
        self.httpd.server_close()


@pytest.mark.parametrize(
    "payload",
    [{"choices": []}, {"choices": [{"message": {"content": None}}]}, {"error": "overloaded"}, {"choices": "nope"}],
)
def test_malformed_payloads_fall_back_not_crash(payload):
    with FakeServer([payload]) as s:
        g = jg.ground("Wave hello to the user!", backend="mllm", url=s.url, retries=1)
    assert g.backend == "embedded (mllm fallback)" and ("chat completion" in g.reason or "text content" in g.reason)
    assert len(s.requests) == 2  # asked again once, then fell back


def test_good_reply_is_used():
    with FakeServer(['{"intent": "embracing", "intensity": "emphatic", "confidence": 0.8}']) as s:
        g = jg.ground("Give them a big hug!", backend="mllm", url=s.url)
    assert (g.intent, g.intensity, g.backend) == ("embracing", "emphatic", "mllm")
    system = s.requests[0]["messages"][0]["content"]
    assert "attentive_listening" in system and '"enum"' in system  # the specification C is rendered


def test_malformed_then_good_reply_is_retried():
    with FakeServer(["sure! the answer is comforting", '{"intent": "comforting", "intensity": "subtle"}']) as s:
        g = jg.ground("They look sad.", backend="mllm", url=s.url)
    assert g.intent == "comforting" and g.backend == "mllm" and len(s.requests) == 2
    assert "invalid" in s.requests[1]["messages"][-1]["content"]


def test_out_of_vocabulary_falls_back_with_reason(caplog):
    with FakeServer(['{"intent": "dancing", "intensity": "moderate"}']) as s:
        g = jg.ground("Nod to agree with the user.", backend="mllm", url=s.url, retries=2)
    assert len(s.requests) == 3 and g.backend.startswith("embedded")
    assert "dancing" in g.reason and g.intent == "nodding"
    assert "fallback" in caplog.text


def test_server_down_falls_back():
    g = jg.ground("Wave goodbye to the user.", backend="mllm", url="http://127.0.0.1:9/v1", timeout_s=2)
    assert g.backend.startswith("embedded") and "fallback" in g.reason and g.intent == "farewell"


def test_response_reasoning_eq2():
    with FakeServer(["The user seems sad; respond calmly with a gentle touch."]) as s:
        text = mllm.reason(
            mllm.Observation(
                visual="a person slumped on a chair", transcript="I failed my exam", tactile=("light stroke",)
            ),
            [("greeting", "moderate")],
            url=s.url,
        )
    assert "sad" in text
    prompt = s.requests[0]["messages"][1]["content"]
    assert "I failed my exam" in prompt and "greeting/moderate" in prompt


def test_parse_reply_rejects_schema_violations():
    with pytest.raises(ValueError, match="intensity"):
        mllm.parse_reply('{"intent": "nodding", "intensity": "huge"}')
    assert mllm.parse_reply('Answer: {"intent": "nodding", "intensity": "subtle"}')[:2] == ("nodding", "subtle")
