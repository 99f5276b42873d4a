"""The users' documentation site (issue 28, "Docs that teach"): mkdocs.yml builds with warnings as errors,
every link and anchor of the built site resolves, and the tutorials render in headless Chromium with
their figures.

The build (`mkdocs build --strict`, the `acl[docs]` extra) replays the commands that draw the tutorials'
figures (docs/hooks/figures.py), about a minute of the shared machine: the build and browser tests are
`studies`.  Without mkdocs, or without Chromium (Debian: `apt-get install chromium`), they skip and say why.
The numbers on the pages are checked by tests/test_docs_sync.py, like every page of docs/."""
from __future__ import annotations

import html.parser
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path
from urllib.parse import unquote, urlsplit

import pytest

ROOT = Path(__file__).resolve().parents[1]
TUTORIALS = ["tutorials/first-device.md", "tutorials/closing-the-loop.md"]
IMAGE = re.compile(r"!\[[^\]]*\]\(([^)\s]+\.png)\)")
CODE = re.compile(r"`[^`\n]*`")             # an image quoted in inline code is text


def _mkdocs():
    pytest.importorskip("mkdocs", reason="the docs site needs the docs extra: pip install -e '.[docs]'")
    pytest.importorskip("material", reason="the docs site needs mkdocs-material: pip install -e '.[docs]'")
    pytest.importorskip("mkdocstrings", reason="the API reference needs mkdocstrings[python]: pip install -e '.[docs]'")


def _env():
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep),
               NO_MKDOCS_2_WARNING="1")
    env.pop("COLUMNS", None)
    return env


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    _mkdocs()
    out = tmp_path_factory.mktemp("site")
    proc = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--clean", "-d", str(out)],
                          cwd=ROOT, env=_env(), capture_output=True, text=True, timeout=1200)
    assert proc.returncode == 0, "mkdocs build --strict failed:\n" + proc.stdout + proc.stderr
    return out


class _Page(html.parser.HTMLParser):
    """The ids, links and images of one HTML page."""

    def __init__(self):
        super().__init__()
        self.ids, self.links, self.images = set(), [], []

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if a.get("id"):
            self.ids.add(a["id"])
        if a.get("name") and tag == "a":
            self.ids.add(a["name"])
        if tag == "a" and a.get("href"):
            self.links.append(a["href"])
        if tag in ("img", "script") and a.get("src"):
            self.images.append(a["src"])
        if tag == "link" and a.get("href"):
            self.links.append(a["href"])


def _parse(path: Path) -> _Page:
    p = _Page()
    p.feed(path.read_text(encoding="utf-8"))
    return p


def _target(page: Path, url: str, site: Path) -> tuple[Path, str] | None:
    """The local file and fragment a relative link of ``page`` points to (None: external)."""
    parts = urlsplit(url)
    if parts.scheme or parts.netloc or url.startswith(("mailto:", "javascript:", "data:")):
        return None
    path = unquote(parts.path)
    if not path:
        return page, parts.fragment
    target = (site / path.lstrip("/")) if path.startswith("/") else (page.parent / path)   # 404.html: from the root
    target = target.resolve()
    if target.is_dir():
        target = target / "index.html"
    return target, parts.fragment


def broken_links(site: Path) -> tuple[list[str], dict]:
    """Every link, script and image of the built pages that points at a missing file or anchor."""
    parsed = {p: _parse(p) for p in sorted(site.rglob("*.html"))}
    broken = []
    for page, doc in parsed.items():
        for url in doc.links + doc.images:
            t = _target(page, url, site)
            if t is None:
                continue
            target, frag = t
            if not target.exists():
                broken.append(f"{page.relative_to(site)}: {url} (no {target})")
            elif frag and target.suffix == ".html":
                ids = parsed[target].ids if target in parsed else _parse(target).ids
                if frag not in ids:
                    broken.append(f"{page.relative_to(site)}: {url} (no anchor #{frag})")
    return broken, parsed


def test_link_check_finds_a_missing_page_a_missing_anchor_and_a_missing_image(tmp_path):
    (tmp_path / "a").mkdir()
    (tmp_path / "a" / "index.html").write_text('<h2 id="here">x</h2><a href="#here">ok</a><a href="../b/#gone">b</a>'
                                               '<a href="../c/">c</a><img src="../f.png"><a href="https://x.org/">ext</a>')
    (tmp_path / "b").mkdir()
    (tmp_path / "b" / "index.html").write_text('<h2 id="there">y</h2><a href="/a/#here">root-relative</a>')
    broken, _ = broken_links(tmp_path)
    assert sorted(b.split(" (")[0] for b in broken) == ["a/index.html: ../b/#gone", "a/index.html: ../c/",
                                                          "a/index.html: ../f.png"], broken


@pytest.mark.studies
def test_site_builds_strict_and_every_internal_link_and_anchor_resolves(site):
    assert (site / "index.html").is_file() and (site / "reference/api/index.html").is_file()
    broken, parsed = broken_links(site)
    assert not broken, "broken links in the built site:\n" + "\n".join(broken[:50])
    # the API reference is generated from docstrings: each public function has its entry
    api = parsed[site / "reference/api/index.html"].ids
    for name in ("load", "analyze", "compile", "lint", "fit", "sweep", "tune"):
        assert any(i.endswith(name) and i.startswith("acl.") for i in api), f"acl.{name} is not in the API reference"


@pytest.mark.studies
def test_every_figure_a_page_links_was_drawn_by_its_commands(site):
    """Each `![..](X.png)` of a tutorial or how-to is in the site, as a PNG drawn at build time."""
    seen = 0
    for md in sorted((ROOT / "docs").rglob("*.md")):
        rel = md.relative_to(ROOT / "docs")
        for img in IMAGE.findall(CODE.sub("", md.read_text(encoding="utf-8"))):
            png = site / rel.parent / img
            assert png.is_file(), f"{rel} links {img}, which the build did not draw"
            assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 5000, png
            seen += 1
    assert seen >= 4, seen


def _chromium() -> str:
    for name in ("chromium", "chromium-browser", "google-chrome", "chrome"):
        exe = shutil.which(name)
        if exe:
            return exe
    pytest.skip("no headless Chromium (Debian: apt-get install chromium); the browser test needs one")


# Once the page has loaded, each image's decoded width is written into the DOM, which --dump-dom prints.
PROBE = ("<script>window.addEventListener('load', function () {"
         "for (const i of document.images) { i.setAttribute('data-natural-width', String(i.naturalWidth)); }"
         "document.body.setAttribute('data-probe', 'loaded'); });</script>")


@pytest.mark.studies
@pytest.mark.parametrize("page", TUTORIALS)
def test_tutorial_renders_in_headless_chromium_with_its_figures(site, page, tmp_path):
    exe = _chromium()
    built = site / page.removesuffix(".md") / "index.html"
    probe = built.with_name("probe.html")
    probe.write_text(built.read_text(encoding="utf-8").replace("</body>", PROBE + "</body>"), encoding="utf-8")
    try:
        proc = subprocess.run([exe, "--headless", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                               f"--user-data-dir={tmp_path / 'profile'}", "--allow-file-access-from-files",
                               "--virtual-time-budget=10000", "--dump-dom", probe.as_uri()],
                              capture_output=True, text=True, timeout=180)
    finally:
        probe.unlink()
    dom = proc.stdout
    assert proc.returncode == 0 and 'data-probe="loaded"' in dom, (
        f"Chromium did not load {page} (exit {proc.returncode}):\n{proc.stderr[-3000:]}")
    title = (ROOT / "docs" / page).read_text(encoding="utf-8").splitlines()[0].lstrip("# ").strip()
    assert title in dom
    assert 'class="md-content"' in dom and dom.count("<pre") >= 3          # the theme laid it out; the outputs are there
    wanted = IMAGE.findall(CODE.sub("", (ROOT / "docs" / page).read_text(encoding="utf-8")))
    assert wanted
    for img in wanted:
        m = re.search(r'<img[^>]*src="[^"]*' + re.escape(img) + r'"[^>]*>', dom)
        assert m, f"{page}: figure {img} is not on the rendered page"
        width = re.search(r'data-natural-width="(\d+)"', m.group(0))
        assert width and int(width.group(1)) > 100, f"{page}: figure {img} did not load in the browser: {m.group(0)}"


def test_figure_hook_draws_a_linked_figure_from_the_pages_own_command(tmp_path):
    """docs/hooks/figures.py on a one-page site: the PNG comes from the page's `acl analyze --plot` run;
    a figure no command draws is left missing (mkdocs --strict then reports the link)."""
    _mkdocs()
    pytest.importorskip("matplotlib", reason="drawing figures needs the plot extra")
    from mkdocs.structure.files import File, Files

    sys.path.insert(0, str(ROOT / "docs" / "hooks"))
    try:
        import figures
    finally:
        sys.path.remove(str(ROOT / "docs" / "hooks"))
    docs = tmp_path / "docs"
    (docs / "t").mkdir(parents=True)
    (docs / "t" / "p.md").write_text(
        "# p\n<!-- doc-run: acl analyze examples/fig2_vertical_cantilever.acl --plot figs/ -->\n"
        "![m](figs/modal_response.png)\n![n](figs/nothing_draws_this.png)\n", encoding="utf-8")
    from mkdocs.config.defaults import MkDocsConfig

    config = MkDocsConfig()
    config.load_dict({"site_name": "t", "docs_dir": str(docs), "site_dir": str(tmp_path / "site")})
    errors, _ = config.validate()
    assert not errors, errors
    files = Files([File("t/p.md", str(docs), str(tmp_path / "site"), True)])
    try:
        out = figures.on_files(files, config)
        uris = {f.src_uri: f for f in out}
        assert "t/figs/modal_response.png" in uris and "t/figs/nothing_draws_this.png" not in uris
        assert Path(uris["t/figs/modal_response.png"].abs_src_path).read_bytes()[:4] == b"\x89PNG"
    finally:
        figures.remove_scratch()
    assert figures.strip_markers("a<!-- doc: = x[0] -->1<!-- /doc -->b<!-- doc-py: y = 1 -->c") == "a1bc"
    quoted = "`<!-- doc: = EXPR -->value<!-- /doc -->` and `<!-- doc-run: acl ARGS -->`"
    assert figures.strip_markers(quoted) == quoted            # docs/contributing.md quotes them
    assert figures.FENCE_WORD.sub(r'\1 title="\2"', "```acl fails\n") == '```acl title="fails"\n'


def test_api_docstrings_render_their_sessions_as_code():
    """docs/hooks/griffe_docstrings.py: a `>>>` session of a docstring becomes a pycon block on the site
    (markdown would read `>>>` as nested quotes), Sphinx roles become code."""
    pytest.importorskip("griffe", reason="the API reference needs mkdocstrings[python]: pip install -e '.[docs]'")
    sys.path.insert(0, str(ROOT / "docs" / "hooks"))
    try:
        import griffe_docstrings as g
    finally:
        sys.path.remove(str(ROOT / "docs" / "hooks"))
    text = "Load it.\n\n>>> import acl\n>>> acl.load(p)\n<Design p>\n\nThen :class:`~acl.notebook.Analysis`."
    out = g.fence_sessions(g.ROLE.sub(r"`\1`", text))
    assert out == ("Load it.\n\n```pycon\n>>> import acl\n>>> acl.load(p)\n<Design p>\n```\n\n"
                   "Then `acl.notebook.Analysis`.")
