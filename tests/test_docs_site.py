"""The docs site builds strict (``make docs``): every page of docs/, the README as its index, the API reference
from the docstrings; a broken link or a docstring mkdocstrings cannot read fails the build."""

import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


def test_the_docs_site_builds_strict(tmp_path):
    pytest.importorskip("mkdocstrings", reason="the docs site's packages are pinned in requirements.txt")
    cmd = [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path / "site")]
    done = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-4000:]
    site = tmp_path / "site"
    index = (site / "index.html").read_text()
    assert "Install, test, reproduce" in index and 'href="how_it_works/"' in index  # README, links into docs/
    linked = re.findall(r"\]\(\.\./results/([^)]+)\)", (ROOT / "docs" / "results.md").read_text())
    assert all((site / "repo" / "results" / name).exists() for name in linked)  # figures outside docs/ come along
    assert "jgrounding.policy.sampling.sample" in (site / "api" / "jg" / "index.html").read_text()
