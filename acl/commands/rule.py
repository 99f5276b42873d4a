"""`acl rule CODE`: print a rule's page (docs/rules.md) or a diagnostic code's entry (docs/*.md tables).

The documentation ships inside the wheel (acl/docs, see pyproject.toml), so this works on an installed
acl as in a checkout.  Reads text only: never imports the lint rules or the physics.
"""
from __future__ import annotations

import json
import os
import re
import sys

from acl.commands._common import add_output_format, report
from acl.diagnostics import Span, error, suggest

_TABLE_ROW = re.compile(r"^\|\s*\[?(ACL\d{3})\]?(?:\(#\w+\))?\s*\|\s*([\w-]+)\s*\|\s*(\w+)\s*\|\s*(\w+)\s*\|\s*$", re.M)
_CODE_ROW = re.compile(r"^\|\s*`?([EWN](?:\d{3}|-[A-Z][A-Z0-9-]*))`?\s*\|\s*(.+?)\s*\|\s*$", re.M)


def add_parser(p) -> None:
    p.add_argument("code", nargs="?", metavar="CODE", help="a lint rule (ACL201) or diagnostic code (E303, W401)")
    p.add_argument("--all", action="store_true", help="list every documented code")
    add_output_format(p)


def _docs() -> str:
    from acl._resources import shipped_dir

    return shipped_dir("docs")


def _read(name: str) -> str:
    with open(os.path.join(_docs(), name), encoding="utf-8") as fh:
        return fh.read()


def rule_pages() -> dict[str, dict]:
    """ACL codes -> {code, name, severity, family, text} from docs/rules.md."""
    text = _read("rules.md")
    table = {m.group(1): m.groups()[1:] for m in _TABLE_ROW.finditer(text)}
    parts = re.split(r"^## (ACL\d{3})\s*$", text, flags=re.M)
    out = {}
    for i in range(1, len(parts), 2):
        code = parts[i]
        body = re.split(r"^## ", parts[i + 1], maxsplit=1, flags=re.M)[0].strip()
        name, severity, family = table.get(code, ("", "", ""))
        out[code] = {"code": code, "name": name, "severity": severity, "family": family,
                     "text": f"## {code}\n\n{body}\n", "source": "docs/rules.md#" + code.lower()}
    return out


def _severity(code: str) -> str:
    return {"W": "warning", "N": "note"}.get(code[0], "error")


def code_entries() -> dict[str, dict]:
    """E/W codes -> {code, text, source} from the code tables of docs/*.md (docs/diagnostics.md first; first definition wins)."""
    out: dict[str, dict] = {}
    for name in sorted(os.listdir(_docs()), key=lambda n: (n != "diagnostics.md", n)):
        if not name.endswith(".md"):
            continue
        for m in _CODE_ROW.finditer(_read(name)):          # docs/rules.md: its lint configuration's code (E-CONFIG)
            code, meaning = m.group(1), m.group(2)
            if code in out:
                if meaning not in out[code]["text"]:
                    out[code]["text"] += f"\n{meaning} (docs/{name})"
                continue
            out[code] = {"code": code, "name": "", "severity": _severity(code),
                         "family": "check", "text": meaning, "source": f"docs/{name}"}
    return out


_EXAMPLE = re.compile(r"```acl (fails|passes)\n")


def with_preamble(text: str) -> str:
    """A rule page whose examples hold the imports docs/rules.md declares once (its ```acl preamble``` block), so
    each example can be pasted into a file as it stands (without them, `use transducer transducers...` was E201)."""
    m = re.search(r"```acl preamble\n(.*?)```", _read("rules.md"), re.S)
    if not m:
        return text
    head = m.group(1)
    return _EXAMPLE.sub(lambda e: e.group(0) + head, text)


def mention(code: str) -> dict | None:
    """A code documented in prose only: the first paragraph of docs/*.md that names it in backticks."""
    for name in sorted(os.listdir(_docs()), key=lambda n: (n != "diagnostics.md", n)):
        if not name.endswith(".md"):
            continue
        for para in re.split(r"\n\s*\n", _read(name)):
            if f"`{code}`" in para:
                return {"code": code, "name": "", "severity": _severity(code),
                        "family": "", "text": para.strip(), "source": f"docs/{name}"}
    return None


def run(args) -> int:
    fmt = args.output_format
    entries = {**code_entries(), **rule_pages()}
    if args.all:
        items = [entries[c] for c in sorted(entries)]
        if fmt == "json":
            sys.stdout.write(json.dumps(items, indent=2) + "\n")
        else:
            for e in items:
                first = e["text"].splitlines()[0] if not e["code"].startswith("ACL") else e["name"]
                sys.stdout.write(f"{e['code']:<8} {first}\n")
        return 0
    if not args.code:
        report([error("E-USAGE", "name a code, e.g. `acl rule ACL201`, or use --all",
                      Span(file="<command line>", line=1, column=1))], fmt)
        return 2
    code = args.code.strip().upper()
    entry = entries.get(code) or (mention(code) if re.fullmatch(r"[EWN][-A-Z0-9]+", code) else None)
    if entry is None:
        report([error("E-USAGE", f"unknown rule or diagnostic code `{args.code}`", Span(file="<command line>", line=1, column=1),
                      suggest(code, entries) or "list them with `acl rule --all`")], fmt)
        return 2
    if fmt == "json":
        sys.stdout.write(json.dumps(entry, indent=2) + "\n")
    elif code.startswith("ACL"):
        sys.stdout.write(f"{code} {entry['name']} (default severity {entry['severity']}, family {entry['family']})\n\n")
        sys.stdout.write(with_preamble(entry["text"]))
    else:
        sys.stdout.write(f"{code} ({entry['severity']}): {entry['text']}\nsee {entry['source']}\n")
    return 0
