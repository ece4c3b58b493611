"""The documentation is a guide: a short README, every page reachable from docs/index.md,
every relative link resolving, and no measurement diary (dates, CI run ids, issue numbers) in
docs/ outside the performance page's date column and the generated reference tables."""
import os
import re

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
DOCS = os.path.join(ROOT, "docs")
LINK = re.compile(r"\]\(([^)#\s]+)(?:#[^)]*)?\)")


def _pages():
    for d, _, files in os.walk(DOCS):
        for f in files:
            if f.endswith(".md"):
                yield os.path.join(d, f)


def _links(page):
    """Relative link targets of a Markdown page, as absolute paths."""
    text = open(page, encoding="utf-8").read()
    return [os.path.normpath(os.path.join(os.path.dirname(page), t))
            for t in LINK.findall(text) if "://" not in t and not t.startswith("mailto:")]


def test_readme_is_short():
    with open(os.path.join(ROOT, "README.md"), encoding="utf-8") as f:
        assert len(f.read().splitlines()) <= 150


def test_every_relative_link_resolves():
    broken = [f"{os.path.relpath(p, ROOT)} -> {os.path.relpath(t, ROOT)}"
              for p in [os.path.join(ROOT, "README.md"), *_pages()]
              for t in _links(p) if not os.path.exists(t)]
    assert not broken, "\n".join(broken)


def test_every_page_is_reachable_from_the_index():
    seen, todo = set(), [os.path.join(DOCS, "index.md")]
    while todo:
        page = todo.pop()
        if page in seen or not page.endswith(".md") or not os.path.isfile(page):
            continue
        seen.add(page)
        todo.extend(_links(page))
    unreachable = sorted(os.path.relpath(p, ROOT) for p in _pages() if p not in seen)
    assert not unreachable, "not linked from docs/index.md (directly or not): " + \
        ", ".join(unreachable)


def test_no_measurement_diary_in_the_docs():
    diary = re.compile(r"\b20\d\d-\d\d-\d\d\b|\bci\d+\b|\b[Ii]ssue \d+\b")
    found = []
    for page in _pages():
        rel = os.path.relpath(page, DOCS)
        if rel.startswith("reference" + os.sep):
            continue                      # generated tables: their generation line is dated
        for n, line in enumerate(open(page, encoding="utf-8"), 1):
            if rel == "performance.md" and line.startswith("|"):
                continue                  # the date column of the current figures
            if diary.search(line):
                found.append(f"{rel}:{n}: {line.strip()[:100]}")
    assert not found, "\n".join(found)
