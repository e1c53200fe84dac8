"""MkDocs hooks of the docs site (``make docs``; mkdocs.yml names this file).

The site's pages are the files of docs/; two things make it read like the repository does:

- README.md is the site's index page (it is written for the repository's front page, so its links into docs/
  are rewritten to the pages they name);
- a file of the repository that a page links to outside docs/ (the figures in results/, CHANGELOG.md) is taken
  into the site under ``repo/`` and the link pointed there, so every relative link of the repository also
  works on the site, and one that points nowhere fails the strict build.
"""

from __future__ import annotations

import posixpath
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"
README = ROOT / "README.md"
LINK = re.compile(r"(\]\()([^)\s#]+)([^)]*\))")  # [text](target#anchor "title")


def _source(src_uri: str) -> Path:
    return README if src_uri == "index.md" else DOCS / src_uri


def _site_path(page_source: Path, target: str) -> str | None:
    """Where a relative link of the page at ``page_source`` lands in the site, or None to leave it alone."""
    if "://" in target or target.startswith(("/", "mailto:")):
        return None
    path = (page_source.parent / target).resolve()
    if path.is_relative_to(DOCS):
        return path.relative_to(DOCS).as_posix()
    if path.is_relative_to(ROOT) and path.is_file():
        return "repo/" + path.relative_to(ROOT).as_posix()
    return None


def _pages() -> list[Path]:
    return [README, *sorted(DOCS.rglob("*.md"))]


def on_files(files, config):
    """Add README.md as ``index.md`` and every outside file a page links to under ``repo/``."""
    from mkdocs.structure.files import File

    files.append(File.generated(config, "index.md", abs_src_path=str(README)))
    added = set()
    for page in _pages():
        for m in LINK.finditer(page.read_text()):
            uri = _site_path(page, m.group(2))
            if uri and uri.startswith("repo/") and uri not in added:
                added.add(uri)
                path = ROOT / uri.removeprefix("repo/")
                files.append(File.generated(config, uri, abs_src_path=str(path)))
    return files


def on_page_markdown(markdown, page, config, files):
    """Point the page's relative links at the site's copies (README's ``docs/x.md`` -> ``x.md``, ...)."""
    source = _source(page.file.src_uri)
    here = posixpath.dirname(page.file.src_uri)

    def fix(m):
        uri = _site_path(source, m.group(2))
        if uri is None:
            return m.group(0)
        return m.group(1) + posixpath.relpath(uri, here or ".") + m.group(3)

    return LINK.sub(fix, markdown)
