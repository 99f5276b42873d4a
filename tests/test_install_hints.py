"""Install instructions a new user can follow (issue 28, tried from a fresh clone).

acl is installed from its source tree and is not on PyPI: `pip install 'acl[plot]'` in a fresh
environment fetches PyPI's unrelated `acl` sdist, which fails to build. The README and the docs
therefore install from the clone (`pip install '.[plot]'`), and a message that names an extra also
gives the checkout form.
"""
from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
# `pip install acl`, `pip install 'acl[plot]'`, `pip install "acl[lsp]"`, `pip install acl[lsp]`
BY_NAME = re.compile(r"""pip install (?:-\S+ )*['"]?acl(?:\[[a-z,]+\])?['"]?(?![\w./-])""")


def _pages():
    yield ROOT / "README.md"
    yield from sorted((ROOT / "docs").rglob("*.md"))
    # the editor packages' own texts: the VS Code extension's message and setting, the Emacs and Neovim headers
    yield from sorted(p for p in (ROOT / "editors").rglob("*")
                      if p.is_file() and p.suffix in (".md", ".js", ".json", ".el", ".lua") and "node_modules" not in p.parts)


def test_readme_docs_and_editors_install_from_the_clone_not_by_name():
    found = [f"{p.relative_to(ROOT)}:{n}: {line.strip()}" for p in _pages()
             for n, line in enumerate(p.read_text(encoding="utf-8").splitlines(), 1) if BY_NAME.search(line)]
    assert not found, "install from the clone (pip install '.[EXTRA]'), acl is not on PyPI:\n" + "\n".join(found)


def test_the_pattern_catches_the_forms_a_page_could_use():
    for bad in ("pip install acl", "pip install 'acl[plot]'", 'pip install "acl[lsp]"', "pip install -U acl[scale]"):
        assert BY_NAME.search(bad), bad
    for good in ("pip install '.[plot]'", "pip install -e '.[test]'", "pip install .", "pip install aclx"):
        assert not BY_NAME.search(good), good


def test_messages_that_name_an_extra_also_give_the_checkout_form():
    missing = []
    for p in sorted((ROOT / "acl").rglob("*.py")):
        text = p.read_text(encoding="utf-8")
        for m in re.finditer(r"pip install '?acl\[([a-z]+)\]'?", text):
            # the checkout form must follow within the same message (a few lines of implicit concatenation)
            if f"pip install '.[{m.group(1)}]'" not in text[m.end():m.end() + 200]:
                missing.append(f"{p.relative_to(ROOT)}:{text.count(chr(10), 0, m.start()) + 1}: acl[{m.group(1)}]")
    assert not missing, "add (from a checkout: pip install '.[EXTRA]'):\n" + "\n".join(missing)
