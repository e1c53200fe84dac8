"""The docs say what the code does: the MLLM page is checked against the client, every relative link in docs/
points at a file, and every ```python block of the README and docs/ runs. (The API reference is built from the
docstrings by `make docs`, strict; the results pages are checked by tests/test_readme.py.)"""

import json
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"


def _block(text: str, name: str) -> str:
    """The fenced block between ``<!-- name:start -->`` and ``<!-- name:end -->``, without the fences."""
    body = text.split(f"<!-- {name}:start -->", 1)[1].split(f"<!-- {name}:end -->", 1)[0].strip()
    return body.split("\n", 1)[1].rsplit("```", 1)[0]


def test_mllm_page_matches_the_client():
    from jgrounding.semantics import mllm

    text = (DOCS / "mllm.md").read_text()
    assert json.loads(_block(text, "schema")) == mllm.SCHEMA
    spec = mllm.grounding_specification().replace(json.dumps(mllm.SCHEMA), "<the schema above, on one line>")
    assert _block(text, "spec").strip() == spec.strip()
    source = (ROOT / "jgrounding" / "semantics" / "mllm.py").read_text()
    assert set(re.findall(r"JGROUNDING_MLLM_\w+", text)) == set(re.findall(r"JGROUNDING_MLLM_\w+", source))
    cfg = mllm.Config()
    for default in (cfg.model, cfg.timeout_s, cfg.retries):
        assert f"`{default}`" in text, default


@pytest.mark.parametrize("page", sorted(p.name for p in DOCS.glob("*.md")))
def test_relative_links_in_docs_resolve(page):
    text = (DOCS / page).read_text()
    for target in re.findall(r"\]\(([^)#\s]+)", text):
        if "://" not in target:
            assert (DOCS / target).exists(), f"{page} links to missing {target}"


# ---------------------------------------------------------------- every ```python block runs
#
# Each page's ```python blocks run in order in one namespace (doctest-style), in a temporary folder, so a
# block that crashes fails the suite. One kind of block is not run: an API signature (one line
# ``name(args) -> type``). Settings that would take minutes are made small by
# the substitutions below; each must still match the page (a stale one fails), so the page shows what runs.
SIGNATURE = re.compile(r"^[\w.]+\(.*\)( -> .+)?\n?$")
SMALL = {  # page -> [(text on the page, what the test runs instead)]
    "distributed.md": [
        (
            'trainer.fit("tuple_spline_rf", lib, seeds=(0, 1, 2, 3, 4), mesh=mesh)',
            'trainer.fit("tuple_spline_rf", lib, seeds=(0,), mesh=mesh, config=__import__("jgrounding.training",'
            ' fromlist=["TrainConfig"]).TrainConfig(steps=2, chunk=2), progress=False)',
        ),
        ("num_samples=30, mesh=mesh", "num_samples=2, mesh=mesh"),
    ],
    "mllm.md": [('url="http://localhost:8000/v1"', "url=FAKE_MLLM_URL")],  # a loopback fake server
    "own_data.md": [('checkpoint="runs/own_data/mine"', "checkpoint=OWN_CHECKPOINT")],  # a 10-step model
}
PAGES = ["README.md"] + [f"docs/{p.name}" for p in sorted(DOCS.glob("*.md"))]


def python_blocks(page: str) -> list[str]:
    return [
        b
        for b in re.findall(r"```python\n(.*?)```", (ROOT / page).read_text(), re.S)
        if not SIGNATURE.match(b.strip() + "\n")
    ]


@pytest.fixture(scope="module")
def fake_mllm():
    """A loopback OpenAI-compatible server that grounds everything to (embracing, emphatic)."""
    import threading
    from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

    class Handler(BaseHTTPRequestHandler):
        def do_POST(self):
            self.rfile.read(int(self.headers["Content-Length"]))
            content = '{"intent": "embracing", "intensity": "emphatic", "confidence": 0.8}'
            data = json.dumps({"choices": [{"message": {"role": "assistant", "content": content}}]}).encode()
            self.send_response(200)
            self.send_header("Content-Type", "application/json")
            self.send_header("Content-Length", str(len(data)))
            self.end_headers()
            self.wfile.write(data)

        def log_message(self, *a):
            pass

    httpd = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
    thread = threading.Thread(target=httpd.serve_forever, daemon=True)
    thread.start()
    yield f"http://127.0.0.1:{httpd.server_address[1]}/v1"
    httpd.shutdown()
    httpd.server_close()


@pytest.mark.parametrize("page", [p for p in PAGES if python_blocks(p)])
def test_python_blocks_run(page, tmp_path, monkeypatch, fake_mllm, request):
    blocks = python_blocks(page)
    name = page.rsplit("/", 1)[-1]
    namespace = {"__name__": "__docs__"}
    for old, new in SMALL.get(name, []):
        assert any(old in b for b in blocks), f"{page} no longer shows {old!r}: update SMALL in tests/test_docs.py"
        blocks = [b.replace(old, new) for b in blocks]
    monkeypatch.chdir(tmp_path)
    if name == "mllm.md":
        from PIL import Image

        Image.new("RGB", (8, 8)).save(tmp_path / "frame.png")  # the page's camera frame
        monkeypatch.setenv("JGROUNDING_MLLM_URL", fake_mllm)
        namespace["FAKE_MLLM_URL"] = fake_mllm
    if name == "own_data.md":
        namespace["OWN_CHECKPOINT"] = str(request.getfixturevalue("own_model")[1])  # tests/conftest.py
    for i, block in enumerate(blocks):
        try:
            exec(compile(block, f"{page} python block {i + 1}", "exec"), namespace)
        except Exception as e:
            raise AssertionError(f"{page}: python block {i + 1} fails: {type(e).__name__}: {e}\n{block}") from e
