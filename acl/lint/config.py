"""Lint configuration: ``[tool.acl.lint]`` in pyproject.toml or ``[lint]`` in a standalone acl.toml.

Found by walking up from the linted file (or the working directory); ``--config PATH`` names one
explicitly.  Every key and code is validated: a mistake is a :class:`ConfigError` carrying
diagnostics that point at the line of the TOML file, never a silent default.

Keys: ``select`` / ``ignore`` (codes, prefixes such as ``ACL1``, or ``ALL``), ``per-file-ignores``
(glob -> codes, globs relative to the configuration file), ``severity`` (code -> error | warning |
info), ``thresholds`` (name -> number in SI, or a string with a unit such as ``"40 um"``),
``mechanics`` (true: confirm ACL201 and evaluate `require gap` with the quasi-static equilibrium,
about a second per drive).
"""
from __future__ import annotations

import fnmatch
import os
import re
from dataclasses import dataclass, field

from acl.diagnostics import Diagnostic, Severity, Span, error, suggest
from acl.lint.registry import THRESHOLDS, match_codes

KEYS = ("select", "ignore", "per-file-ignores", "severity", "thresholds", "mechanics")
CHECK_CODE = re.compile(r"^[EW]\d{3}$")


class ConfigError(Exception):
    def __init__(self, diagnostics: list[Diagnostic]):
        self.diagnostics = diagnostics
        super().__init__(diagnostics[0].message if diagnostics else "configuration error")


@dataclass
class LintConfig:
    select: tuple[str, ...] | None = None          # expanded codes; None = every rule
    ignore: tuple[str, ...] = ()
    per_file_ignores: tuple[tuple[str, tuple[str, ...]], ...] = ()
    severity: dict[str, Severity] = field(default_factory=dict)
    thresholds: dict[str, float] = field(default_factory=dict)
    mechanics: bool = False                        # confirm with the (slow) quasi-static equilibrium
    root: str = "."                                # folder the globs are relative to
    path: str | None = None                        # the file it came from

    def threshold(self, name: str) -> float:
        return self.thresholds.get(name, THRESHOLDS[name].default)

    def enabled(self, code: str) -> bool:
        if code in self.ignore:
            return False
        return self.select is None or code in self.select

    def ignored_for(self, path: str) -> set[str]:
        out: set[str] = set()
        rel = os.path.relpath(os.path.abspath(path), os.path.abspath(self.root)).replace(os.sep, "/")
        for pattern, codes in self.per_file_ignores:
            if fnmatch.fnmatch(rel, pattern) or fnmatch.fnmatch(os.path.basename(path), pattern):
                out.update(codes)
        return out


# ----------------------------------------------------------------------------------------------
# Discovery
# ----------------------------------------------------------------------------------------------

def find_config(start: str) -> str | None:
    """The nearest acl.toml, or pyproject.toml with a [tool.acl.lint] table, walking up from ``start``."""
    d = os.path.abspath(start if os.path.isdir(start) else os.path.dirname(os.path.abspath(start)))
    while True:
        cand = os.path.join(d, "acl.toml")
        if os.path.isfile(cand):
            return cand
        cand = os.path.join(d, "pyproject.toml")
        if os.path.isfile(cand) and _has_lint_table(cand):
            return cand
        parent = os.path.dirname(d)
        if parent == d:
            return None
        d = parent


def _has_lint_table(path: str) -> bool:
    try:
        with open(path, encoding="utf-8") as fh:
            text = fh.read()
    except OSError:
        return False
    return re.search(r"^\s*\[\s*tool\.acl\.lint(\s*\]|\.)", text, re.M) is not None or "tool.acl.lint" in text


def load_config(path: str | None, rules: dict) -> LintConfig:
    """Read and validate a configuration file; ``None`` gives the defaults."""
    if path is None:
        return LintConfig()
    import tomllib

    span0 = Span(file=path, line=1, column=1)
    try:
        with open(path, "rb") as fh:
            raw = fh.read()
        text = raw.decode("utf-8-sig")      # a byte-order mark (Windows editors) as in .acl and .csv files
        from acl._files import MAX_INT_DIGITS, overlong_integer

        long_int = overlong_integer(text)
        if long_int is not None:
            raise ConfigError([error("E-CONFIG", f"invalid TOML: a number of more than {MAX_INT_DIGITS} digits",
                                     Span(file=path, line=long_int[0], column=long_int[1]))])
        data = tomllib.loads(text)
    except FileNotFoundError:
        raise ConfigError([error("E-CONFIG", f"configuration file `{path}` not found", span0)]) from None
    except UnicodeDecodeError as exc:          # located at the byte, as data files (acl.fit.data, E807)
        from acl._files import undecodable

        line, column, byte = undecodable(raw, exc)
        raise ConfigError([error("E-CONFIG", f"cannot read `{path}`: not UTF-8 text (byte 0x{byte:02x})",
                                 Span(file=path, line=line, column=column), "save the file as UTF-8")]) from None
    except OSError as exc:
        raise ConfigError([error("E-CONFIG", f"cannot read `{path}`: {exc.strerror or exc}", span0)]) from None
    except tomllib.TOMLDecodeError as exc:
        m = re.search(r"line (\d+), column (\d+)", str(exc))
        span = Span(file=path, line=int(m.group(1)), column=int(m.group(2))) if m else span0
        raise ConfigError([error("E-CONFIG", f"invalid TOML: {exc}", span)]) from None
    # `tool = 1` or `[tool] acl = 5` is a located error, not an AttributeError on .get (was E-INTERNAL)
    locate = _Locator(text, path)
    tool = _subtable(data, "tool", "", locate)
    acl = _subtable(tool, "acl", "tool", locate)
    if os.path.basename(path) == "pyproject.toml":
        table = acl.get("lint", {})
        prefix = "tool.acl.lint"
    else:
        table = data.get("lint", acl.get("lint", {}))
        prefix = "lint" if "lint" in data else "tool.acl.lint"
    return _parse(table, text, path, prefix, rules)


def _subtable(parent: dict, key: str, parent_name: str, locate) -> dict:
    """``parent[key]`` when it is a table (empty when absent); a ConfigError located at the key otherwise."""
    value = parent.get(key, {})
    if isinstance(value, dict):
        return value
    name = f"{parent_name}.{key}" if parent_name else key
    raise ConfigError([error("E-CONFIG", f"`{name}` must be a table", locate(parent_name, key),
                             "acl reads [tool.acl.lint] (pyproject.toml), or [lint] (acl.toml)")])


def _parse(table: dict, text: str, path: str, prefix: str, rules: dict) -> LintConfig:
    locate = _Locator(text, path)
    diags: list[Diagnostic] = []
    cfg = LintConfig(root=os.path.dirname(os.path.abspath(path)), path=path)

    def bad(msg: str, key: str, table_name: str = prefix, hint: str | None = None):
        diags.append(error("E-CONFIG", msg, locate(table_name, key), hint))

    if not isinstance(table, dict):
        raise ConfigError([error("E-CONFIG", f"`{prefix}` must be a table", locate(prefix, None))])
    for key in table:
        if key not in KEYS:
            bad(f"unknown key `{key}` in [{prefix}]", key, hint=suggest(key, KEYS) or "keys: " + ", ".join(KEYS))

    def codes(value, where: str, key: str, table_name: str = prefix, allow_check: bool = False) -> tuple[str, ...]:
        if isinstance(value, str):
            value = [value]
        if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
            bad(f"`{where}` must be a list of rule codes", key, table_name)
            return ()
        out: list[str] = []
        for v in value:
            if allow_check and CHECK_CODE.match(v.strip().upper()):
                out.append(v.strip().upper())
                continue
            found = match_codes(v, rules)
            if not found:
                bad(f"unknown rule code `{v}` in `{where}`", key, table_name,
                    suggest(v.upper(), rules) or "see `acl lint --list-rules`")
            out.extend(found)
        return tuple(dict.fromkeys(out))

    if "mechanics" in table:
        if not isinstance(table["mechanics"], bool):
            bad("`mechanics` must be true or false", "mechanics")
        else:
            cfg.mechanics = table["mechanics"]
    if "select" in table:
        cfg.select = codes(table["select"], "select", "select")
        if table["select"] in ([], "", [""]):     # selected no rule: every design "passed" with nothing checked
            bad("`select` is empty: no rule would run", "select", hint="list codes or prefixes, or remove `select`")
    if "ignore" in table:
        cfg.ignore = codes(table["ignore"], "ignore", "ignore", allow_check=True)
    pfi = table.get("per-file-ignores", {})
    if not isinstance(pfi, dict):
        bad("`per-file-ignores` must be a table of glob = [codes]", "per-file-ignores")
    else:
        cfg.per_file_ignores = tuple(
            (glob, codes(v, f"per-file-ignores.{glob}", glob, f"{prefix}.per-file-ignores", allow_check=True))
            for glob, v in pfi.items())
    sev = table.get("severity", {})
    if not isinstance(sev, dict):
        bad("`severity` must be a table of code = \"error\" | \"warning\" | \"info\"", "severity")
    else:
        for code, level in sev.items():
            found = match_codes(code, rules)
            if not found:
                bad(f"unknown rule code `{code}` in `severity`", code, f"{prefix}.severity", suggest(code.upper(), rules))
                continue
            if level not in ("error", "warning", "info"):
                bad(f"severity of `{code}` must be \"error\", \"warning\" or \"info\", not {level!r}", code,
                    f"{prefix}.severity")
                continue
            for c in found:
                cfg.severity[c] = Severity(level)
    th = table.get("thresholds", {})
    if not isinstance(th, dict):
        bad("`thresholds` must be a table of name = value", "thresholds")
    else:
        for name, value in th.items():
            where = f"{prefix}.thresholds"
            if name not in THRESHOLDS:
                bad(f"unknown threshold `{name}`", name, where,
                    suggest(name, THRESHOLDS) or "thresholds: " + ", ".join(THRESHOLDS))
                continue
            v = _threshold_value(value, THRESHOLDS[name].unit)
            if isinstance(v, str):
                bad(f"threshold `{name}`: {v}", name, where)
                continue
            cfg.thresholds[name] = v
    if diags:
        raise ConfigError(diags)
    return cfg


def _threshold_value(value, unit: str) -> float | str:
    """The SI value of a threshold, or a message saying what is wrong with it."""
    if isinstance(value, bool):
        return "expected a number"
    if isinstance(value, (int, float)):
        v = float(value)
    elif isinstance(value, str):
        from acl.units import UnitError, parse_unit, parse_unit_static

        m = re.match(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*(.*?)\s*$", value)
        if not m:
            return f"cannot read {value!r}; write a number or a quantity such as \"40 um\""
        num, u = float(m.group(1)), m.group(2)
        try:
            factor, dims = parse_unit(u) if u else (1.0, parse_unit_static(""))
        except UnitError as exc:
            return str(exc)
        if dims != parse_unit_static(unit):
            return f"{value!r} has the wrong dimension (expected {unit or 'a plain number'})"
        v = num * factor
    else:
        return "expected a number"
    if not v > 0:
        return "must be positive"
    if not v < float("inf"):
        return "must be positive and finite"
    return v


class _Locator:
    """Find the line of ``key`` inside ``table`` of a TOML text (best effort; line 1 otherwise)."""

    HEADER = re.compile(r"^\s*\[\s*([^\]]+?)\s*\]\s*(#.*)?$")

    def __init__(self, text: str, path: str):
        self.lines = text.splitlines()
        self.path = path

    def __call__(self, table: str, key: str | None) -> Span:
        current = ""
        fallback = None
        key_re = re.compile(r'(^|[\s{,])["\']?' + re.escape(key) + r'["\']?\s*=') if key else None
        for i, line in enumerate(self.lines, 1):
            m = self.HEADER.match(line)
            if m:
                current = m.group(1).replace(" ", "").replace('"', "")
                if key is None and current == table:
                    return Span(file=self.path, line=i, column=1)
                continue
            if key_re is None:
                continue
            km = key_re.search(line)
            if km:
                col = km.start() + len(km.group(1)) + 1
                if current == table or table.startswith(current + ".") and current:
                    return Span(file=self.path, line=i, column=col)
                if fallback is None and (current == "" or table.startswith(current)):
                    fallback = Span(file=self.path, line=i, column=col)
        return fallback or Span(file=self.path, line=1, column=1)
