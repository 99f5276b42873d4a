"""Finding and loading acl modules: stdlib, sibling files, search paths; import safety and cycles."""
from __future__ import annotations

import functools
import os
from dataclasses import dataclass, field

from acl.diagnostics import DiagnosticBag, DiagnosticError, Span
from acl.syntax import ast as A
from acl.syntax.parser import parse_module


def stdlib_root() -> str:
    from acl._resources import shipped_dir

    return shipped_dir("stdlib")


@dataclass
class ModuleEnv:
    """One loaded file: its syntax and a symbol table of its top-level names."""

    file: str
    module: A.Module
    decls: dict[str, A.Block] = field(default_factory=dict)
    params: dict[str, A.ParamDecl] = field(default_factory=dict)
    imports: dict[str, object] = field(default_factory=dict)   # alias -> ModuleEnv | (ModuleEnv, name)
    programs: dict[str, A.ProgramDecl] = field(default_factory=dict)
    statements: list = field(default_factory=list)   # own statements, after those of an `extends` base
    base: "ModuleEnv | None" = None
    is_main: bool = False


MAX_FILES = 256      # files one design may read (itself, its imports and extends)
MAX_CHAIN = 64       # files importing or extending each other in one chain


class Loader:
    """Loads a module and its imports once each; only from allowed roots."""

    def __init__(self, bag: DiagnosticBag, search_paths=(), max_files: int = MAX_FILES):
        self.bag = bag
        self.search_paths = [os.path.realpath(p) for p in search_paths]
        self.search_given = list(search_paths)       # as the user wrote them: names shown in diagnostics
        self.cache: dict[str, ModuleEnv] = {}
        self.stack: list[str] = []
        self.sources: list[str] = []
        self.max_files = max_files
        self.opened = 0          # files read so far (a chain counts as much as a wide import)

    # ------------------------------------------------------------------------------------------
    def load_main(self, path: str) -> ModuleEnv:
        real = os.path.realpath(path)
        text = _read(path)
        env = self._load_text(text, path, real, root=os.path.dirname(real))
        env.is_main = True
        return env

    def load_text(self, text: str, filename: str) -> ModuleEnv:
        real = os.path.realpath(filename) if os.path.exists(filename) else filename
        folder = os.path.dirname(os.path.abspath(filename))   # imports of `--stdin-filename dir/x.acl` start in dir
        root = os.path.realpath(folder) if os.path.isdir(folder) else os.getcwd()
        env = self._load_text(text, filename, real, root=root)
        env.is_main = True
        return env

    def _load_text(self, text: str, display: str, real: str, root: str) -> ModuleEnv:
        self.opened += 1
        self.stack.append(real)
        self.sources.append(display)
        try:
            try:
                module = _parse_cached(text, display)
            except DiagnosticError as exc:
                for d in exc.diagnostics:
                    self.bag.add(d)
                module = A.Module(display, (), text)
            env = ModuleEnv(display, module)
            self._index(env, root)
            self.cache[real] = env
            return env
        finally:
            self.stack.pop()

    # ------------------------------------------------------------------------------------------
    def _index(self, env: ModuleEnv, root: str) -> None:
        seen: dict[str, Span] = {}

        def claim(name: str, span: Span) -> bool:
            if name in seen:
                self.bag.error("E205", f"`{name}` is declared twice (first at {seen[name]})", span,
                               "give each declaration its own name")
                return False
            seen[name] = span
            return True

        own = list(env.module.statements)
        extends = [st for st in own if isinstance(st, A.Extends)]
        for extra in extends[1:]:
            self.bag.error("E215", "a design extends at most one file", extra.span)
        if extends:
            base = self._extends(extends[0], env, root)
            if base is not None:
                env.base = base
                env.imports.update(base.imports)
                env.decls.update(base.decls)
                env.params.update(base.params)
                env.programs.update(base.programs)
                overridden = {st.name for st in own if isinstance(st, (A.ParamDecl, A.Block, A.ProgramDecl))}
                for st in base.statements:
                    if isinstance(st, (A.ParamDecl, A.Block, A.ProgramDecl)) and st.name in overridden:
                        continue
                    env.statements.append(st)
                for name in base.decls:
                    seen[name] = base.decls[name].span
        env.statements.extend(own)
        base_names = set(env.base.params) | set(env.base.decls) | {"program " + p for p in env.base.programs} if env.base else set()
        for st in own:
            if isinstance(st, A.Extends):
                continue
            if isinstance(st, A.Import):
                target = self._import(st, env, root)
                if target is not None:
                    alias = st.alias or (st.module[-1] if st.module else None)
                    if alias and claim(alias, st.span):
                        env.imports[alias] = target
            elif isinstance(st, A.ParamDecl):
                if st.name in base_names and st.name in env.params:
                    env.params[st.name] = st       # a calibrated value replaces the base's
                    seen[st.name] = st.span
                elif claim(st.name, st.span):
                    env.params[st.name] = st
            elif isinstance(st, A.Block):
                if st.name in base_names and st.name in env.decls and env.decls[st.name].kind == st.kind:
                    env.decls[st.name] = st
                    seen[st.name] = st.span
                elif claim(st.name, st.span):
                    env.decls[st.name] = st
            elif isinstance(st, A.ProgramDecl):
                if "program " + st.name in base_names:
                    env.programs[st.name] = st
                elif claim("program " + st.name, st.span):
                    env.programs[st.name] = st
            elif isinstance(st, A.ObserveDecl):
                claim(st.name, st.span)

    def _extends(self, st: A.Extends, env: ModuleEnv, root: str) -> "ModuleEnv | None":
        here = os.path.dirname(os.path.realpath(env.file)) if os.path.exists(env.file) else root
        cand = os.path.join(here, st.file)
        if not os.path.isfile(cand):
            self.bag.error("E208", f"cannot find `{st.file}` to extend", st.span)
            return None
        real = os.path.realpath(cand)
        if not self.allowed(real, root):
            self.bag.error("E210", f"`{st.file}` is outside the design's directory tree", st.span,
                           "pass its folder with --path to allow it")
            return None
        if real in self.stack:
            self.bag.error("E209", f"extends cycle through `{st.file}`", st.span)
            return None
        if not self._room(st, "extends"):
            return None
        text = self._read(cand)
        shown = shown_path(cand, real, os.path.join(os.path.dirname(env.file), st.file))
        return None if text is None else self._load_text(text, shown, real, root=os.path.dirname(real))

    def _read(self, path: str) -> str | None:
        """A file's text, or None after recording why it cannot be read."""
        try:
            return _read(path)
        except DiagnosticError as exc:
            for d in exc.diagnostics:
                self.bag.add(d)
            return None

    def _import(self, st: A.Import, env: ModuleEnv, root: str):
        here = os.path.dirname(os.path.realpath(env.file)) if os.path.exists(env.file) else root
        # each candidate with the name diagnostics give it: from the importing file's name and the --path
        # folders as the user wrote them (`parts/beam.acl`, not /home/.../parts/beam.acl); the stdlib's own
        mine = os.path.dirname(env.file)
        guesses: dict[str, str] = {}
        if st.file is not None:
            candidates = [os.path.join(here, st.file)]
            guesses[candidates[0]] = os.path.join(mine, st.file)
            shown = st.file
            member = None
        else:
            parts = st.module
            shown = ".".join(parts)
            candidates = []
            member = None
            if parts[0] == "stdlib":
                base = [(stdlib_root(), None)]
                rel = parts[1:]
            else:
                base = [(here, mine), *zip(self.search_paths, self.search_given)]
                rel = parts
            for b, g in base:
                candidates.append(os.path.join(b, *rel) + ".acl")
                if g is not None:
                    guesses[candidates[-1]] = os.path.join(g, *rel) + ".acl"
            if len(rel) >= 2:  # `import stdlib.media.pbs`: module media, member pbs
                member = rel[-1]
                for b, g in base:
                    candidates.append((os.path.join(b, *rel[:-1]) + ".acl", member))
                    if g is not None:
                        guesses[candidates[-1][0]] = os.path.join(g, *rel[:-1]) + ".acl"
        for cand in candidates:
            mem = None
            if isinstance(cand, tuple):
                cand, mem = cand
            if not os.path.isfile(cand):
                continue
            real = os.path.realpath(cand)
            if not self.allowed(real, root):
                self.bag.error("E210", f"import `{shown}` resolves outside the design's directory tree",
                               st.span, "imports may only reach the importing file's folder and below, the stdlib, and --path folders")
                return None
            if real in self.stack:
                chain = " -> ".join(os.path.basename(p) for p in self.stack[self.stack.index(real):] + [real])
                self.bag.error("E209", f"import cycle: {chain}", st.span, "move shared declarations into a third file")
                return None
            target = self.cache.get(real)
            if target is None:
                if not self._room(st, "import"):
                    return None
                text = self._read(cand)
                if text is None:
                    return None
                target = self._load_text(text, shown_path(cand, real, guesses.get(cand)), real,
                                         root=os.path.dirname(real) if real.startswith(stdlib_root()) else root)
            if mem is not None:
                if mem not in target.decls and mem not in target.params:
                    continue
                return (target, mem)
            return target
        from acl.diagnostics import suggest

        hint = None
        if st.module and st.module[0] == "stdlib":
            names = _stdlib_modules()
            hint = suggest(".".join(st.module[1:]), names) or ("stdlib modules: " + ", ".join(sorted(names)))
        self.bag.error("E208", f"cannot find module `{shown}`", st.span, hint)
        return None

    def _room(self, st, what: str) -> bool:
        """Whether one more file may be read for `st`; records the limit's diagnostic if not."""
        if self.opened >= self.max_files:
            self.bag.error("E211", f"more than {self.max_files} files imported or extended", st.span,
                           "a design reads at most this many files, counting chains of imports")
            return False
        if len(self.stack) >= MAX_CHAIN:
            self.bag.error("E211", f"{what} chain deeper than {MAX_CHAIN} files", st.span,
                           f"files importing each other through {MAX_CHAIN} levels: flatten the chain")
            return False
        return True

    def allowed(self, real: str, root: str) -> bool:
        """Whether a file may be read: under the design's folder, the stdlib or a --path folder."""
        roots = [os.path.realpath(root), os.path.realpath(stdlib_root()), *self.search_paths]
        return any(real == r or real.startswith(r.rstrip(os.sep) + os.sep) for r in roots)


def shown_path(cand: str, real: str, guess: str | None) -> str:
    """The name diagnostics give a file a design reads (extends, imports): ``guess``, the path built from the
    importing file's name as the user gave it (normalised: `sub/../base.acl` is `base.acl`), when it names
    the same file; else ``cand`` (absolute: the importing file was a link into another folder, or the stdlib)."""
    if guess is None:
        return cand
    guess = os.path.normpath(guess)
    try:
        return guess if os.path.realpath(guess) == real else cand
    except (OSError, ValueError):
        return cand


PARSED_MODULES: dict[tuple[str, str], A.Module] = {}


def _parse_cached(text: str, display: str) -> A.Module:
    """Parse once per (file, content) in a process: linting many designs reuses stdlib modules.

    Syntax trees are immutable, so sharing them is safe; files with errors are not cached.
    """
    key = (display, text)
    hit = PARSED_MODULES.get(key)
    if hit is None:
        hit = parse_module(text, display)
        if len(PARSED_MODULES) > 512:
            PARSED_MODULES.clear()
        PARSED_MODULES[key] = hit
    return hit


@functools.lru_cache(maxsize=1)
def stdlib_modules() -> tuple[str, ...]:
    """Dotted names of the stdlib's modules (`media`, `capsules`, ...)."""
    return tuple(_stdlib_modules())


def _stdlib_modules() -> list[str]:
    out = []
    base = stdlib_root()
    for dirpath, _dirs, files in os.walk(base):
        for f in files:
            if f.endswith(".acl"):
                rel = os.path.relpath(os.path.join(dirpath, f[:-4]), base)
                out.append(rel.replace(os.sep, "."))
    return out


MAX_BYTES = 2_000_000


def read_source(path: str, limit: int = MAX_BYTES) -> str:
    """The UTF-8 text of a regular file, reading at most ``limit + 1`` bytes; DiagnosticError if not.

    A FIFO, a device (a design symlinked to /dev/zero) or a socket is refused before any read, so
    nothing hangs or fills memory; the size limit counts bytes read, not what `stat` claims (/proc
    files say 0). Standard input is read by the commands (`-` with `--stdin-filename`), not here.
    """
    import stat

    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_BINARY", 0))
    except FileNotFoundError:
        raise DiagnosticError([_io_error(path, "no such file")]) from None
    except IsADirectoryError:
        raise DiagnosticError([_io_error(path, "is a directory, not a design file")]) from None
    except OSError as exc:
        raise DiagnosticError([_io_error(path, exc.strerror or str(exc))]) from None
    try:
        mode = os.fstat(fd).st_mode
        if stat.S_ISDIR(mode):
            raise DiagnosticError([_io_error(path, "is a directory, not a design file")])
        if not stat.S_ISREG(mode):
            kind = "a FIFO" if stat.S_ISFIFO(mode) else "a device" if stat.S_ISCHR(mode) or stat.S_ISBLK(mode) \
                else "a socket" if stat.S_ISSOCK(mode) else "not a regular file"
            raise DiagnosticError([_io_error(path, f"is {kind}, not a regular file",
                                             hint="pass a design file, or `-` to read standard input")])
        chunks, n = [], 0
        while n <= limit:
            chunk = os.read(fd, min(1 << 20, limit + 1 - n))
            if not chunk:
                break
            chunks.append(chunk)
            n += len(chunk)
        if n > limit:
            raise DiagnosticError([_io_error(path, f"file larger than {limit // 1_000_000} MB",
                                             hint="split the design into imported files")])
        raw = b"".join(chunks)
    except OSError as exc:
        raise DiagnosticError([_io_error(path, exc.strerror or str(exc))]) from None
    finally:
        os.close(fd)
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as exc:       # located at the byte (was 1:1 with its offset)
        from acl.diagnostics import error
        from acl._files import undecodable

        line, column, byte = undecodable(raw, exc)
        raise DiagnosticError([error("E103", f"cannot read `{path}`: not UTF-8 text (byte 0x{byte:02x} cannot be "
                                     "decoded)", Span(file=path, line=line, column=column),
                                     "save the file as UTF-8; units such as `µm` can be written `um`")]) from None


_read = read_source


def _io_error(path: str, msg: str, code: str = "E601", hint: str | None = None):
    from acl.diagnostics import error

    return error(code, f"cannot read `{path}`: {msg}", Span(file=path, line=1, column=1), hint)
