"""Compare `acl lint` findings between two checkouts: every example, stdlib and test-data design and
generated designs (benchmarks/check.py) of the given sizes.

    python benchmarks/lint_compare.py dump ROOT OUT.json [--sizes 1000,2500,5000]
    python benchmarks/lint_compare.py diff BEFORE.json AFTER.json

``dump`` lints with the `acl` on PYTHONPATH (run it once with PYTHONPATH=<old checkout>, once with the new
one; ROOT is the checkout whose files are linted) and writes code, severity, message, location, hint and
notes of every finding; ``diff`` prints the files whose findings differ (exit status 1 if any).  Issue 23's
rework of lint's analysis was checked this way against ec2441c: identical on all of them.
"""
from __future__ import annotations

import argparse
import importlib.util
import json
import sys
import tempfile
import time
from pathlib import Path


def dump(root: Path, out: str, sizes: list[int]) -> None:
    from acl.lint import LintConfig, lint_file

    spec = importlib.util.spec_from_file_location("acl_benchmark_check", root / "benchmarks" / "check.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    files = sorted(str(p) for pattern in ("examples/*.acl", "stdlib/*.acl", "samples/**/*.acl", "benchmarks/designs/*.acl")
                   for p in root.glob(pattern))
    res = {}
    with tempfile.TemporaryDirectory() as tmp:
        for n in sizes:
            p = Path(tmp) / f"generated_{n}.acl"
            p.write_text(mod.generate(n))
            files.append(str(p))
        for f in files:
            t = time.process_time()
            r = lint_file(f, LintConfig())
            key = f.replace(str(root), "ROOT").replace(tmp, "GENERATED")
            res[key] = [[d.code, str(d.severity), d.message,
                         [d.span.file.replace(str(root), "ROOT").replace(tmp, "GENERATED"), d.span.line, d.span.column]
                         if d.span else None, d.hint, list(d.notes)] for d in r.findings]
            print(f"{time.process_time() - t:8.2f} s CPU {len(res[key]):6d} findings  {key}", flush=True)
    Path(out).write_text(json.dumps(res, indent=0))


def diff(before: str, after: str) -> int:
    a, b = json.loads(Path(before).read_text()), json.loads(Path(after).read_text())
    bad = sorted(k for k in a.keys() | b.keys() if a.get(k) != b.get(k))
    for k in bad:
        print(f"differs: {k} ({len(a.get(k) or [])} vs {len(b.get(k) or [])} findings)")
    print(f"{len(a.keys() & b.keys())} files compared, {sum(len(v) for v in a.values())} findings before; "
          f"{len(bad)} differ")
    return 1 if bad else 0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    d = sub.add_parser("dump")
    d.add_argument("root", type=Path)
    d.add_argument("out")
    d.add_argument("--sizes", default="1000,2500")
    c = sub.add_parser("diff")
    c.add_argument("before")
    c.add_argument("after")
    args = ap.parse_args()
    if args.cmd == "dump":
        dump(args.root.resolve(), args.out, [int(x) for x in args.sizes.split(",") if x])
        return 0
    return diff(args.before, args.after)


if __name__ == "__main__":
    sys.exit(main())
