"""The docs say what the code does: the API reference is regenerated and compared, the MLLM page is
checked against the client, and every relative link in docs/ points at a file."""

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


def test_api_reference_is_up_to_date():
    from tools import api_docs

    assert (DOCS / "api.md").read_text() == api_docs.render(), "docs/api.md is stale: run `python -m tools.api_docs`"


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
