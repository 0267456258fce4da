"""The user documentation: README.md stays a short user's document, and every relative link
in README.md and docs/*.md points to a file (and heading anchor, where one is given) that exists."""
import glob
import os
import re

import pytest

from builders import TESTS


ROOT = os.path.join(TESTS, "..")
PAGES = [os.path.join(ROOT, "README.md")] + sorted(glob.glob(os.path.join(ROOT, "docs", "*.md")))
LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)\)")


def _anchors(path):
    """GitHub's heading anchors of a Markdown file (lower case, punctuation dropped, spaces
    to hyphens, repeated headings numbered -1, -2, ...)."""
    seen, out = {}, set()
    in_code = False
    for line in open(path, encoding="utf-8"):
        if line.startswith("```"):
            in_code = not in_code
        if in_code or not re.match(r"#{1,6} ", line):
            continue
        slug = re.sub(r"[^\w\- ]", "", line.lstrip("#").strip().lower()).replace(" ", "-")
        n = seen.get(slug, 0)
        seen[slug] = n + 1
        out.add(slug if n == 0 else f"{slug}-{n}")
    return out


def _links(path):
    text = re.sub(r"```.*?```", "", open(path, encoding="utf-8").read(), flags=re.S)
    text = re.sub(r"`[^`\n]*`", "", text)
    return [m.group(1) for m in LINK.finditer(text)]


@pytest.mark.parametrize("page", PAGES, ids=lambda p: os.path.relpath(p, ROOT))
def test_relative_links_resolve(page):
    bad = []
    for link in _links(page):
        if re.match(r"[a-z][a-z0-9+.-]*:", link):          # http:, https:, mailto:
            continue
        target, _, anchor = link.partition("#")
        path = os.path.normpath(os.path.join(os.path.dirname(page), target)) if target else page
        if not os.path.exists(path):
            bad.append(f"{link}: no file {os.path.relpath(path, ROOT)}")
        elif anchor and (not path.endswith(".md") or anchor not in _anchors(path)):
            bad.append(f"{link}: no heading #{anchor}")
    assert not bad, f"{os.path.relpath(page, ROOT)}: " + "; ".join(bad)


def test_every_docs_page_is_in_the_index():
    index = os.path.join(ROOT, "docs", "README.md")
    linked = {os.path.normpath(os.path.join(ROOT, "docs", t.partition("#")[0]))
              for t in _links(index)}
    missing = [os.path.basename(p) for p in PAGES[1:]
               if p != index and os.path.normpath(p) not in linked]
    assert not missing, f"docs/README.md does not link {missing}"


def test_readme_stays_short():
    n = sum(1 for _ in open(os.path.join(ROOT, "README.md"), encoding="utf-8"))
    assert n < 400, f"README.md has {n} lines (keep it under 400: details go to docs/)"
