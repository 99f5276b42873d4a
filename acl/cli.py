"""The `acl` command line: thin. Parses arguments, calls one stage function, renders the result.

Each subcommand lives in ``acl/commands/<name>.py`` and exposes ``add_parser(subparsers)`` and
``run(args) -> int``.  Command modules are imported lazily so `acl check` stays fast.
Exit codes: 0 clean, 1 errors in the design / findings / infeasible, 2 usage or I/O error.
"""
from __future__ import annotations

import argparse
import errno
import importlib
import os
import sys

COMMANDS = {
    "check": "Parse and type-check designs (units, names, geometry, printability).",
    "show": "Print the resolved design as a tree, or as JSON.",
    "analyze": "Predict resonances, forces, equilibria and latch margins.",
    "compile": "Compile a program into a drive-signal schedule and waveform files.",
    "lint": "Run design rules (for CI): rule codes, configuration, machine-readable output.",
    "fit": "Fit the model to measured data, find missing effects, report before/after.",
    "synth": "Generate synthetic measurement data from a design (to test analyses).",
    "rule": "Print the documentation of a rule or diagnostic code (e.g. ACL201, E303).",
    "fmt": "Rewrite designs in the one canonical layout (--check for CI, --diff, - for stdin).",
    "sweep": "Sweep parameters over grids and print tolerances (Monte Carlo): a table per point and the yield.",
    "export": "Write the printable solid of a design (.stl, .3mf, .obj), checked against the design.",
    "tune": "Choose the free parameters that maximise the yield of every require under print tolerances.",
    "play": "Play a compiled schedule on a signal generator (SCPI over PyVISA; --dry-run prints it).",
    "track": "Track a capsule in a microscope video (AVI, MP4, TIFF stack) into the CSV `acl fit` reads.",
    "lsp": "Start the language server (LSP over stdio) for editors; needs acl[lsp].",
}

EPILOG = """\
examples:
  acl check examples/fig2_vertical_cantilever.acl
  acl show examples/fig3_three_orifice.acl --output-format json
  acl analyze examples/fig4h_unequal_pair.acl --at "85 kHz @ 5 V"
  acl compile examples/fig3_three_orifice.acl --program circle -o out/
  acl lint examples/ --output-format github
  acl rule ACL201
  acl fit design.acl data.csv --report fit/
  acl fmt examples/ --check
  acl sweep design.acl --vary radius=8um..12um:41 --tolerance "radius=normal(0, 150 nm)" -o sweep.csv
  acl play out/schedule.json --dry-run
  acl track run.avi -o data.csv --scale 0.65 --roi 50,42,40,40 --schedule out/schedule.json

exit codes: 0 clean, 1 errors in the design or findings, 2 usage or I/O error.
docs: docs/language.md, docs/physics.md, docs/rules.md, docs/data.md, docs/bench.md
"""


def usage_location(message: str) -> str:
    """Where on the command line an argparse error is: ``<--option>:1:1``, ``<PATH>:1:1``, ``<argv>:1:1``.

    As every option diagnostic (``<--at>:1:COLUMN``): the option as the file, line 1, the column in
    its value (argparse rejects a whole argument: column 1).
    """
    import re

    m = (re.match(r"argument ([^:\s]+)", message)
         or re.match(r"unrecognized arguments: (\S+)", message)
         or re.match(r"the following arguments are required: ([^,\s]+)", message))
    if not m:
        return "<argv>:1:1"
    # an option as named (`--prog=x` at `<--prog>`, `-o/--output` at `<--output>`), anything else as given
    where = m.group(1).split("=", 1)[0].split("/")[-1] if m.group(1).startswith("-") else m.group(1)
    return f"<{where}>:1:1"


class _Parser(argparse.ArgumentParser):
    """acl's parser (the root and every subcommand): no abbreviations, located usage errors.

    argparse takes a unique prefix of an option for the option (`--prog` for `--program`); a script
    written so breaks the day a new option shares the prefix.  An abbreviation is an unknown option
    (E-USAGE, exit 2) with a `did you mean` of the full name instead.
    """

    def __init__(self, *args, **kwargs):
        kwargs.setdefault("allow_abbrev", False)
        super().__init__(*args, **kwargs)

    def error(self, message: str):  # usage errors: a located diagnostic line and exit 2, no traceback
        self.print_usage(sys.stderr)
        sys.stderr.write(f"{usage_location(message)}: error[E-USAGE]: {message}\n")
        raise SystemExit(2)


def unrecognized(parser: argparse.ArgumentParser, args, extra: list[str]) -> None:
    """Exit 2 on arguments no parser took: the command's usage (not acl's), and for a mistyped
    option the closest one the command has (`--programm` -> `--program`)."""
    from acl.diagnostics import suggest

    target = parser
    if getattr(args, "command", None) and hasattr(args, "_module"):
        target = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices[args.command]
    longs = [o for a in target._actions for o in a.option_strings if o.startswith("--")]
    first = next((e.split("=", 1)[0] for e in extra if e.startswith("--")), None)
    # compared without the leading dashes, which every option shares (with them `--bogus` was `--verbose`)
    hint = suggest(first[2:], {o[2:]: o for o in longs}) if first else None
    target.print_usage(sys.stderr)
    message = "unrecognized arguments: " + " ".join(extra)
    sys.stderr.write(f"{usage_location(message)}: error[E-USAGE]: {message}\n")
    if hint:
        sys.stderr.write(f"      = help: {hint.replace('`', '`--', 1)}\n")
    raise SystemExit(2)


def build_parser(argv: list[str] | None = None) -> argparse.ArgumentParser:
    """The whole command line; only the command named in ``argv`` (default: sys.argv) is imported."""
    from acl import __version__

    parser = _Parser(
        prog="acl",
        description="acl: a language and compiler for acoustically programmable soft micro-mechanisms.",
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"acl {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    argv = sys.argv[1:] if argv is None else argv
    wanted = next((a for a in argv if a in COMMANDS), None)
    for name, help_text in COMMANDS.items():
        if wanted is not None and name != wanted:
            sub.add_parser(name, help=help_text)   # cheap placeholder, keeps --help complete
            continue
        try:
            module = importlib.import_module(f"acl.commands.{name}")
        except ModuleNotFoundError:
            continue
        p = sub.add_parser(name, help=help_text, description=help_text,
                           formatter_class=argparse.RawDescriptionHelpFormatter)
        module.add_parser(p)
        from acl.commands import add_verbosity

        add_verbosity(p)
        p.set_defaults(_module=module)
    return parser


def repeated_option(parser: argparse.ArgumentParser, tokens: list[str]) -> tuple[str, list[str]] | None:
    """(option, its values) of the first single-valued option given more than once in ``tokens`` (one
    subcommand's arguments), else None.  argparse keeps the last value silently: `--program a --program b`
    compiled b, `-o a.csv -o b.csv` wrote b.csv.  Repeatable options (append), flags and counts are not
    single-valued."""
    by_string = {}
    for a in parser._actions:
        for o in a.option_strings:
            by_string[o] = a
    seen: dict[int, tuple[str, list[str]]] = {}
    i = 0
    while i < len(tokens):
        tok = tokens[i]
        i += 1
        if tok == "--":
            break
        if not tok.startswith("-") or tok == "-":
            continue
        name, attached = (tok.split("=", 1) + [None])[:2] if tok.startswith("--") else (tok[:2], tok[2:] or None)
        action = by_string.get(name)        # no abbreviations: the parsers have allow_abbrev=False
        if action is None:
            continue
        takes = action.nargs is None or action.nargs == "?"
        if not isinstance(action, (argparse._StoreAction, argparse._AppendAction)) or not takes:
            continue
        value = attached
        if value is None and i < len(tokens) and (action.nargs is None or not tokens[i].startswith("-")):
            value = tokens[i]
            i += 1
        if isinstance(action, argparse._AppendAction):
            continue
        key = id(action)
        first = seen.setdefault(key, (action.option_strings[-1], []))
        first[1].append(value if value is not None else "")
        if len(first[1]) > 1:
            return first
    return None


class Terminated(KeyboardInterrupt):
    """SIGTERM or SIGHUP, raised where the program is, so every cleanup that runs on Ctrl-C runs too."""


#: The signal that asked acl to stop (0: none yet).  An interrupt that lands inside a compiled extension's import
#: (pydantic_core's import of `datetime`) comes back as that extension's own error (pyo3's PanicException, a
#: BaseException), not as KeyboardInterrupt; knowing a signal came lets main() report it as the interrupt it is.
_SIGNALLED = 0


#: True once main() is restoring the handlers: a signal then only sets _SIGNALLED (main() reports it), as an
#: exception raised there would escape main() as a traceback.
_QUIET_SIGNALS = False


def _terminate(signum, frame):
    global _SIGNALLED
    _SIGNALLED = signum
    if not _QUIET_SIGNALS:
        raise Terminated(signum)


def _interrupt(signum, frame):
    """Ctrl-C as Python's default handler does it (KeyboardInterrupt), remembered for main()."""
    global _SIGNALLED
    _SIGNALLED = signum
    if not _QUIET_SIGNALS:
        raise KeyboardInterrupt


#: Held while a signal is sent again (below) and while main() stops signals: no signal is sent after that.
_REDELIVERY = None


def _redeliver(signum):
    import time

    time.sleep(0.02)                    # the hook has long returned: the signal lands where the command can unwind
    with _REDELIVERY:
        if not _QUIET_SIGNALS:
            os.kill(os.getpid(), signum)


def _unraisable(info):
    """An interrupt that lands in a callback Python cannot raise from (a weakref callback of the import system)
    is not lost and prints no traceback: the signal is sent again from a helper thread once this hook has
    returned (sent from here, its handler would raise inside the hook, and Python would print that and drop it).
    If the command ends first, main() still reports the signal (_SIGNALLED)."""
    import signal
    import threading

    if info.exc_type is not None and issubclass(info.exc_type, KeyboardInterrupt):
        global _SIGNALLED
        signum = (int(info.exc_value.args[0]) if isinstance(info.exc_value, Terminated) and info.exc_value.args
                  else int(signal.SIGINT))
        _SIGNALLED = signum
        threading.Thread(target=_redeliver, args=(signum,), daemon=True, name="acl-signal").start()
        return
    sys.__unraisablehook__(info)


def _on_termination():
    """Make SIGTERM and SIGHUP unwind like Ctrl-C (the temporary files and folders of every writer are removed
    on the way out); returns the handlers to restore.  Before, `timeout` or a batch scheduler's SIGTERM
    killed a compile at once and left 1-2 GB of half-written waveform in `.acl-compile-*/`."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        return {}
    sys.unraisablehook = _unraisable
    old = {}
    for sig, handler in ((signal.SIGTERM, _terminate), (getattr(signal, "SIGHUP", None), _terminate),
                         (signal.SIGINT, _interrupt)):
        if sig is None:
            continue
        try:
            previous = signal.getsignal(sig)
            if previous is signal.SIG_IGN or (sig == signal.SIGINT and previous is not signal.default_int_handler):
                continue                        # nohup: a hang-up stays ignored; a host's own Ctrl-C handler stays
            old[sig] = signal.signal(sig, handler)
        except (ValueError, OSError):
            pass
    return old


class _ClosedStream:
    """Standard output when the shell closed it (`acl check x.acl >&-`): writing to it is an error (E601), not
    silence: a script must not take a missing result for an empty one."""

    encoding = "utf-8"
    errors = "strict"

    def write(self, text):
        import errno

        raise OSError(errno.EBADF, "standard output is closed")

    def flush(self):
        pass

    def isatty(self):
        return False

    def fileno(self):
        import io

        raise io.UnsupportedOperation("standard output is closed")


_STREAM_ERRNOS = frozenset(getattr(errno, n) for n in ("EIO", "EBADF", "EFBIG", "ENOSPC", "EDQUOT") if hasattr(errno, n))


def _prepare_streams() -> None:
    """Standard streams acl can always use.

    * A closed descriptor 0, 1 or 2 (`<&-`, `>&-`) is filled with /dev/null, so no file acl opens lands on it
      (and is then written by a print); a closed standard output raises E601 at the first write.
    * Text that the stream's encoding cannot carry is replaced, not an internal error: a file name that is not
      UTF-8 (its surrogate escapes written as ``\\udcff``), the table ellipsis under PYTHONIOENCODING=ascii."""
    import io
    import os

    closed = []
    for fd in (0, 1, 2):
        try:
            os.fstat(fd)
        except OSError:
            try:
                new = os.open(os.devnull, os.O_RDWR)
                if new != fd:
                    os.dup2(new, fd)
                    os.close(new)
                closed.append(fd)
            except OSError:
                pass
    if 1 in closed:
        sys.stdout = _ClosedStream()
    if 2 in closed:
        sys.stderr = open(os.devnull, "w", encoding="utf-8")
    for stream in (sys.stdout, sys.stderr):
        enc = (getattr(stream, "encoding", None) or "").lower().replace("-", "").replace("_", "")
        try:
            stream.reconfigure(errors="backslashreplace" if enc in ("utf8", "utf8sig") else "replace")
        except (AttributeError, ValueError, io.UnsupportedOperation):
            pass


def _stream_error(exc: OSError) -> int:
    """E601 for a standard output that cannot be written (closed, a full disk, /dev/full), exit 2; the stream is
    pointed at /dev/null so the interpreter's last flush does not fail again."""
    import os

    try:
        fd = os.open(os.devnull, os.O_WRONLY)
        os.dup2(fd, 1)
        os.close(fd)
    except OSError:
        pass
    try:
        sys.stderr.write(f"<stdout>:1:1: error[E601]: cannot write standard output: {exc.strerror or exc}\n")
    except (OSError, ValueError):
        pass
    return 2


def _terminated(exc: Terminated) -> int:
    import signal

    signum = int(exc.args[0]) if exc.args else int(signal.SIGTERM)
    try:
        sys.stderr.write(f"acl: terminated ({signal.Signals(signum).name})\n")
    except (OSError, ValueError, AttributeError):
        pass
    return 128 + signum


def main(argv: list[str] | None = None) -> int:
    import threading

    global _SIGNALLED, _QUIET_SIGNALS, _REDELIVERY
    _SIGNALLED = 0
    _QUIET_SIGNALS = False
    _REDELIVERY = threading.Lock()
    hook = sys.unraisablehook
    old = _on_termination()
    code = 0
    try:
        try:
            code = _run(argv)
        except KeyboardInterrupt:      # a signal between the command's end and here: reported below
            pass
    finally:
        import signal

        _QUIET_SIGNALS = True          # from here a signal is only remembered
        with _REDELIVERY:              # and none is sent again
            pass
        for sig, handler in old.items():
            signal.signal(sig, handler)
        sys.unraisablehook = hook
    if _SIGNALLED and code not in (130, 128 + _SIGNALLED):
        # the signal arrived where it could not unwind the command (a hook, the last flush): the command may
        # have finished, but the caller asked it to stop and learns that it did not end normally
        return _signalled(_SIGNALLED)
    return code


def _signalled(signum: int) -> int:
    import signal

    if signum == signal.SIGINT:
        try:
            sys.stderr.write("acl: interrupted\n")
        except (OSError, ValueError):
            pass
        return 130
    return _terminated(Terminated(signum))


def _run(argv: list[str] | None) -> int:
    import warnings

    _prepare_streams()
    try:
        with warnings.catch_warnings():
            if not os.environ.get("ACL_DEBUG"):
                # a Python warning (numpy's overflow in an extreme design, a library's deprecation) is no
                # diagnostic: acl reports what it finds as located W codes, or nothing (ACL_DEBUG=1 shows them)
                warnings.simplefilter("ignore")
            code = _main(argv)
        try:
            sys.stdout.flush()
        except OSError as exc:
            return _stream_error(exc)
        except ValueError:             # the command closed standard output itself (the language server)
            pass
        return code
    except Terminated as exc:          # before or after the command ran (argument parsing, the last flush)
        return _terminated(exc)
    except KeyboardInterrupt:          # Ctrl-C while the command's modules are imported
        import signal

        return _signalled(int(signal.SIGINT))
    except SystemExit:
        raise
    except BaseException:              # a signal that surfaced as an extension's error during an import
        if not _SIGNALLED:
            raise
        return _signalled(_SIGNALLED)


def _main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    parser = build_parser(argv)
    args, extra = parser.parse_known_args(argv)
    if extra:
        unrecognized(parser, args, extra)
    if not getattr(args, "command", None) or not hasattr(args, "_module"):
        parser.print_help()
        return 2
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices[args.command]
    twice = repeated_option(sub, argv[argv.index(args.command) + 1:])
    if twice:
        option, values = twice
        sys.stderr.write(f"<{option}>:1:1: error[E-USAGE]: {option} given twice ({values[0]!r}, then {values[1]!r}): "
                         "it takes one value, and the last would silently win\n")
        return 2
    if not getattr(args, "quiet", False):
        for note in getattr(args, "deprecated_options", None) or []:
            sys.stderr.write(f"acl: warning: {note}\n")
    import time

    from acl.diagnostics import DiagnosticError

    start = time.perf_counter()
    try:
        code = int(args._module.run(args) or 0)
        if getattr(args, "verbose", False):
            sys.stderr.write(f"acl {args.command}: exit {code} after {time.perf_counter() - start:.2f} s\n")
        return code
    except Terminated as exc:
        return _terminated(exc)
    except KeyboardInterrupt:
        sys.stderr.write("acl: interrupted\n")
        return 130
    except DiagnosticError as exc:     # a stage that stops the whole command (a folder search at its limit: E602)
        from acl.commands import exit_code, report

        fmt = getattr(args, "output_format", "text")
        report(exc.diagnostics, fmt if fmt == "json" else "text")
        return max(exit_code(exc.diagnostics), 1)
    except BrokenPipeError:
        return 0
    except OSError as exc:
        if exc.filename is None and exc.errno in _STREAM_ERRNOS:
            return _stream_error(exc)
        return _internal(exc)
    except Exception as exc:  # last resort: never a traceback for the user
        return _internal(exc)


def _internal(exc: Exception) -> int:
    """The last resort: never a traceback for the user (ACL_DEBUG=1 prints it)."""
    import os
    import traceback

    if _SIGNALLED:     # the signal surfaced as an extension's error (pydantic-core's SchemaError around the interrupt)
        return _signalled(_SIGNALLED)
    sys.stderr.write(f"acl: internal error[E-INTERNAL]: {type(exc).__name__}: {exc}\n")
    if os.environ.get("ACL_DEBUG"):
        traceback.print_exc()
    else:
        sys.stderr.write("acl: set ACL_DEBUG=1 for a traceback, and please report it.\n")
    return 2


if __name__ == "__main__":
    sys.exit(main())
