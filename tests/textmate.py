"""A small TextMate grammar interpreter, enough to test editors/vscode/syntaxes/acl.tmLanguage.json.

It follows the tokenizer editors use (vscode-textmate): lines are scanned one at a time with a
newline appended; at each position every pattern of the current rule is searched and the
leftmost match wins (the earliest-listed on a tie, the enclosing rule's `end` first); `match`
rules scope their text and `captures`; `begin`/`end` rules push and pop a scope; `include`
resolves `#name` (repository), `$self` and `$base`. Regexes run on Python's `re` or, when the
`onigurumacffi` package is installed, on Oniguruma itself (the engine editors use).
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field


class PythonEngine:
    name = "python-re"

    def compile(self, pattern: str):
        rx = re.compile(pattern)

        def search(line: str, pos: int):
            m = rx.search(line, pos)
            return None if m is None else [m.span(i) for i in range(rx.groups + 1)]
        return search


class OnigurumaEngine:
    name = "oniguruma"

    def __init__(self):
        import onigurumacffi

        self._onig = onigurumacffi

    def compile(self, pattern: str):
        rx = self._onig.compile(pattern)
        n = rx.number_of_captures()

        def search(line: str, pos: int):
            m = rx.search(line, pos)
            return None if m is None else [m.span(i) for i in range(n + 1)]
        return search


@dataclass
class _Frame:
    rule: dict
    patterns: list
    end: object = None          # compiled end search, for begin/end rules
    scopes: tuple = field(default_factory=tuple)


class Grammar:
    def __init__(self, data: dict, engine=None):
        self.data = data
        self.engine = engine or PythonEngine()
        self._compiled: dict[str, object] = {}

    def _search(self, pattern: str):
        if pattern not in self._compiled:
            self._compiled[pattern] = self.engine.compile(pattern)
        return self._compiled[pattern]

    def compile_all(self) -> int:
        """Compile every regex of the grammar; returns how many there are."""
        n = 0

        def walk(rule):
            nonlocal n
            for key in ("match", "begin", "end"):
                if key in rule:
                    self._search(rule[key])
                    n += 1
            for r in rule.get("patterns", []):
                walk(r)
        walk(self.data)
        for r in self.data.get("repository", {}).values():
            walk(r)
        return n

    def _expand(self, patterns, seen=()) -> list[dict]:
        out = []
        for p in patterns:
            inc = p.get("include")
            if inc is None:
                if "match" in p or "begin" in p:
                    out.append(p)
                else:   # a rule holding only patterns
                    out.extend(self._expand(p.get("patterns", []), seen))
                continue
            if inc in ("$self", "$base"):
                target = self.data
            elif inc.startswith("#"):
                target = self.data["repository"][inc[1:]]
            else:
                raise ValueError(f"external include {inc!r} not supported")
            key = id(target)
            if key in seen:
                continue
            if "match" in target or "begin" in target:
                out.append(target)
            else:
                out.extend(self._expand(target.get("patterns", []), seen + (key,)))
        return out

    def tokenize(self, text: str) -> list[tuple[str, tuple[str, ...]]]:
        """Per character of ``text``: (character, scopes), outermost scope first."""
        root = self.data["scopeName"]
        stack = [_Frame(self.data, self._expand(self.data.get("patterns", [])), None, (root,))]
        out: list[tuple[str, tuple[str, ...]]] = []
        for raw in text.splitlines(keepends=True):
            body = raw.rstrip("\r\n")
            line = body + "\n"
            scopes = self._line(line, stack)
            out.extend((ch, scopes[i]) for i, ch in enumerate(body))
            out.extend((ch, (root,)) for ch in raw[len(body):])
        return out

    def _line(self, line: str, stack: list[_Frame]) -> list[tuple[str, ...]]:
        result: list[tuple[str, ...]] = [()] * len(line)
        pos = 0
        while pos < len(line):
            frame = stack[-1]
            best = None   # (start, order, kind, rule, spans)
            if frame.end is not None:
                spans = frame.end(line, pos)
                if spans is not None:
                    best = (spans[0][0], -1, "end", frame.rule, spans)
            for order, rule in enumerate(frame.patterns):
                spans = self._search(rule.get("match") or rule["begin"])(line, pos)
                if spans is not None and (best is None or spans[0][0] < best[0]):
                    best = (spans[0][0], order, "match" if "match" in rule else "begin", rule, spans)
            if best is None:
                for i in range(pos, len(line)):
                    result[i] = frame.scopes
                break
            start, _, kind, rule, spans = best
            end = spans[0][1]
            for i in range(pos, start):
                result[i] = frame.scopes
            if kind == "end":
                self._paint(result, spans, frame.scopes, rule.get("endCaptures") or rule.get("captures"))
                stack.pop()
            elif kind == "match":
                scopes = frame.scopes + ((rule["name"],) if "name" in rule else ())
                self._paint(result, spans, scopes, rule.get("captures"))
            else:
                scopes = frame.scopes + ((rule["name"],) if "name" in rule else ())
                self._paint(result, spans, scopes, rule.get("beginCaptures") or rule.get("captures"))
                end_src = re.sub(r"\\(\d)", lambda m: re.escape(line[slice(*spans[int(m.group(1))])]), rule["end"])
                inner = scopes + ((rule["contentName"],) if "contentName" in rule else ())
                stack.append(_Frame(rule, self._expand(rule.get("patterns", [])), self._search(end_src), inner))
            if end == pos and kind == "match":   # an empty match: move on, as editors do
                result[pos] = result[pos] or frame.scopes
                end = pos + 1
            pos = end
        return result

    @staticmethod
    def _paint(result, spans, scopes, captures) -> None:
        s, e = spans[0]
        for i in range(s, e):
            result[i] = scopes
        for k, cap in sorted((captures or {}).items(), key=lambda kv: int(kv[0])):
            k = int(k)
            if k >= len(spans) or "name" not in cap:
                continue
            cs, ce = spans[k]
            for i in range(max(cs, s), min(ce, e)):
                result[i] = result[i] + (cap["name"],)
