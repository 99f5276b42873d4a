"""mkdocs hook: the figures a page shows are drawn, at build time, by the commands the page itself runs.

A page links a figure by the path the page's commands write it to, relative to the page, e.g.
``![...](figs/modal_response.png)`` after ``acl analyze ... --plot figs/``.  For every page that links a
missing ``.png``, this hook replays the page's ``<!-- doc-run: ... -->``, ``<!-- doc: $ ... -->`` and
``<!-- doc-py: ... -->`` markers in order, in a scratch folder (``tests/docs_sync.py``'s session: copies of
``examples/`` and ``samples/``), until every linked figure exists, and adds those PNGs to the site
beside the page.  Nothing is committed or written to the repository: a figure cannot drift from the run
that draws it, and a figure no command draws is a missing link (an error under ``mkdocs build --strict``).

Nav entries for pages that do not exist (yet) are dropped with a note, so the nav can name pages other
branches add. It also prepares each page's markdown for the site without changing the file: each ``<!-- doc ... -->``
marker is replaced by what it generated (markers are invisible, but their Python expressions look like
reference links to mkdocs-autorefs), and docs/rules.md's fences ```` ```acl fails ```` / ```` ```acl passes ```` (the
info string tests/test_lint_docs.py reads) become ```` ```acl title="fails" ````.
"""
from __future__ import annotations

import atexit
import logging
import re
import sys
from pathlib import Path, PurePosixPath

from mkdocs.structure.files import File

log = logging.getLogger("mkdocs.hooks.figures")
ROOT = Path(__file__).resolve().parents[2]
FENCE_WORD = re.compile(r"^(\s*```acl) (fails|passes|preamble)[ \t]*$", re.M)
IMAGE = re.compile(r"!\[[^\]]*\]\((?P<path>[^)\s]+\.png)\)")
CODE = re.compile(r"`[^`\n]*`")             # an image quoted in inline code is text
_sessions: dict = {}      # (page, its text) -> the session that drew its figures; kept while mkdocs runs
                          # (`mkdocs serve` rebuilds without replaying unchanged pages), removed at exit


def _docs_sync():
    if str(ROOT / "tests") not in sys.path:
        sys.path.insert(0, str(ROOT / "tests"))
    if str(ROOT) not in sys.path:
        sys.path.insert(0, str(ROOT))
    import docs_sync

    return docs_sync


def _draw(page: str, text: str, wanted: list[str]) -> Path:
    """Replay the page's commands until every wanted figure exists: the scratch folder."""
    ds = _docs_sync()
    if (page, text) in _sessions:
        return Path(_sessions[page, text].dir)
    for key in [k for k in _sessions if k[0] == page]:     # the page changed: its old figures go
        _sessions.pop(key).close()
    session = _sessions[page, text] = ds.Session(page)
    scratch = Path(session.dir)
    for m in ds.MARK.finditer(text):
        if all((scratch / w).is_file() for w in wanted):
            break
        if m.group("run") is not None:
            session.acl(*ds._exit(m.group("run")))
        elif m.group("py") is not None:
            session.run_py(m.group("py"))
        elif m.group("key").strip().startswith("$"):
            session.acl(*ds._exit(m.group("key").strip()[1:]))
    return scratch


def _prune(nav, docs: Path):
    out = []
    for item in nav:
        if isinstance(item, dict):
            (title, value), = item.items()
            if isinstance(value, list):
                value = _prune(value, docs)
                if value:
                    out.append({title: value})
                continue
            item_path = value
        else:
            item_path = item
        if isinstance(item_path, str) and item_path.endswith(".md") and "://" not in item_path \
                and not (docs / item_path).is_file():
            log.info("nav: %s is not in docs/ (yet): left out", item_path)
            continue
        out.append(item)
    return out


def on_config(config):
    if config["nav"]:
        config["nav"] = _prune(config["nav"], Path(config["docs_dir"]))
    return config


def on_files(files, config):
    existing = {f.src_uri for f in files}
    for page in [f for f in files if f.src_uri.endswith(".md")]:
        text = Path(page.abs_src_path).read_text(encoding="utf-8")
        base = PurePosixPath(page.src_uri).parent
        wanted = sorted({m.group("path") for m in IMAGE.finditer(CODE.sub("", text))
                         if "://" not in m.group("path") and str(base / m.group("path")) not in existing})
        if not wanted or "<!-- doc" not in text:
            continue
        src = Path(page.abs_src_path)
        scratch = _draw(str(src.relative_to(ROOT)) if src.is_relative_to(ROOT) else page.src_uri, text, wanted)
        for w in wanted:
            if not (scratch / w).is_file():
                continue            # left missing: mkdocs --strict reports the link
            uri = str(base / w)
            figure = File(uri, src_dir=None, dest_dir=config["site_dir"], use_directory_urls=config["use_directory_urls"])
            figure.abs_src_path = str(scratch / w)      # as File.generated (mkdocs 1.6), outside a plugin run
            files.append(figure)
            existing.add(uri)
            log.info("figure %s drawn by the commands of %s", uri, page.src_uri)
    return files


def strip_markers(markdown: str) -> str:
    """The page as a reader sees it: each marker replaced by what it generated (docs_sync.MARK, so a marker
    quoted in inline code stays)."""
    return _docs_sync().MARK.sub(lambda m: m.group("body") or "", markdown)


def on_page_markdown(markdown, page, config, files):
    return FENCE_WORD.sub(r'\1 title="\2"', strip_markers(markdown))


@atexit.register
def remove_scratch():
    while _sessions:
        _sessions.popitem()[1].close()
