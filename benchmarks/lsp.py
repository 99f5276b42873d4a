"""Benchmark of `acl lsp`: time from didChange to publishDiagnostics on a 1,000-line design.

    python benchmarks/lsp.py [--lines 1000] [--runs 10] [--lint]

Spawns `python -m acl lsp` and speaks the protocol (tests/lsp_client.py), opens a generated design
(benchmarks/check.py's generator), warms up, then changes one line per run and measures from
sending didChange to receiving the publishDiagnostics of that version (the check-stage
diagnostics; lint findings follow later from a worker process).  The server's debounce (the pause
it waits for before checking, 50 ms by default) is included.  Target: median < 150 ms.
"""
from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT / "benchmarks"))

from check import generate  # noqa: E402
from lsp_client import LspClient  # noqa: E402

TARGET_MS = 150.0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--lines", type=int, default=1000)
    ap.add_argument("--runs", type=int, default=10)
    ap.add_argument("--warmup", type=int, default=3)
    ap.add_argument("--lint", action="store_true", help="also run lint in the server's worker (competes for CPU)")
    args = ap.parse_args()
    text = generate(args.lines)
    n_lines = text.count("\n")
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "big.acl"
        path.write_text(text, encoding="utf-8")
        client = LspClient({"lint": args.lint})
        try:
            u = client.open(path, text, 1)
            client.wait_for("textDocument/publishDiagnostics", lambda p: p["uri"] == u and p.get("version") == 1)
            lines = text.split("\n")
            mid = next(i for i in range(len(lines) // 2, len(lines)) if lines[i].startswith("param x"))
            results = {}
            v = 1
            for case in ("edit a line in the middle", "append a line at the end"):
                times = []
                for i in range(args.warmup + args.runs):
                    v += 1
                    if case.startswith("edit"):
                        new = lines[:mid] + [lines[mid].replace("* pitch", f"* pitch + {i + 1} um")] + lines[mid + 1:]
                        body = "\n".join(new)
                    else:
                        body = text + f"param bench_{i} = {i + 1} um\n"
                    t0 = time.perf_counter()
                    client.change(u, v, body)
                    pub = client.wait_for("textDocument/publishDiagnostics",
                                          lambda p, v=v: p["uri"] == u and p.get("version") == v)
                    assert pub["diagnostics"] == [], pub["diagnostics"][:3]
                    if i >= args.warmup:
                        times.append((pub["_t"] - t0) * 1e3)
                    time.sleep(0.1)
                results[case] = times
            debounce = 50.0
        finally:
            client.close()
    import os

    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"acl lsp: didChange -> publishDiagnostics on a {n_lines}-line design ({args.runs} runs after "
          f"{args.warmup} warm-up, debounce {debounce:.0f} ms included{', lint worker on' if args.lint else ''}; "
          f"load average {load:.1f} on {os.cpu_count()} CPUs):")
    for case, times in results.items():
        med = statistics.median(times)
        print(f"  {case}: median {med:.1f} ms, min {min(times):.1f} ms, max {max(times):.1f} ms "
              f"(target < {TARGET_MS:.0f} ms: {'met' if med < TARGET_MS else 'NOT met'})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
