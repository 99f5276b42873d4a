"""Behaviour check for a refactor of the compiler: compile every program of every example (plus a few option
variants) with the acl checked out at SRC into OUT, then compare two OUT folders.

    git archive BASE | tar -x -C /tmp/base            # the commit to compare against
    python tests/compile_reference.py /tmp/base /tmp/ref
    python tests/compile_reference.py . /tmp/new
    python tests/compile_reference.py --compare /tmp/ref /tmp/new     # exit 1 on any difference

Compared: exit code, stdout and stderr (numbers to 1e-9 relative), schedule.json and segments.csv (floats to
1e-12 relative), waveform.npy (1e-12), waveform.wav and sequence.seq (bytes).  About a minute on 2 cores
(J=2 parallel compiles).  Used to prove the split of acl/schedule/compile.py into passes changed no output.
"""
from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

VARIANTS = {  # extra runs exercising option paths
    "fig3_three_orifice:circle": [["--robust"], ["--nonlinear-passes", "1"], ["--output-format", "json"]],
    "fig2_stroke:ramp": [["--robust", "worst"], ["--band-samples", "0"]],
}
NUM = re.compile(r"-?\d+\.?\d*(?:[eE][-+]?\d+)?")


def programs(src: str) -> dict:
    """{example stem: [program names]} as the acl at ``src`` reads them."""
    code = ("import acl, json\nfrom pathlib import Path\n"
            "print(json.dumps({p.stem: [g.name for g in acl.load(str(p)).programs]\n"
            "                  for p in sorted(Path('examples').glob('*.acl'))}))")
    r = subprocess.run([sys.executable, "-c", code], cwd=src, env={**os.environ, "PYTHONPATH": src},
                       capture_output=True, text=True, check=True)
    return json.loads(r.stdout)


def one(src: str, out: str, stem: str, prog: str, extra: list, tag: str) -> str:
    d = Path(out) / f"{stem}__{prog}{tag}"
    d.mkdir(parents=True, exist_ok=True)
    cmd = [sys.executable, "-m", "acl", "compile", f"examples/{stem}.acl", "--program", prog, "-o", str(d / "o"),
           "--format", "wav,npy,seq", *extra]
    t0 = time.time()
    r = subprocess.run(cmd, cwd=src, capture_output=True, text=True,
                       env={**os.environ, "PYTHONPATH": src, "COLUMNS": "120", "NO_COLOR": "1"})
    (d / "stdout").write_text(r.stdout.replace(str(d / "o"), "OUT"))
    (d / "stderr").write_text(r.stderr.replace(str(d / "o"), "OUT"))
    (d / "rc").write_text(str(r.returncode))
    return f"{stem}:{prog}{tag} rc={r.returncode} {time.time() - t0:.1f}s"


def run(src: str, out: str) -> None:
    jobs = []
    for stem, progs in programs(src).items():
        for p in progs:
            jobs.append((stem, p, [], ""))
            jobs += [(stem, p, ex, f"__v{i}") for i, ex in enumerate(VARIANTS.get(f"{stem}:{p}", []))]
    with ThreadPoolExecutor(int(os.environ.get("J", "2"))) as ex:
        for msg in ex.map(lambda j: one(src, out, *j), jobs):
            print(msg, flush=True)


def close(a: float, b: float, rel: float = 1e-12) -> bool:
    return a == b or abs(a - b) <= rel * max(abs(a), abs(b)) + 1e-300


def cmp_text(a: str, b: str) -> str | None:
    if a == b:
        return None
    la, lb = [x.rstrip() for x in a.splitlines()], [x.rstrip() for x in b.splitlines()]   # padding: path length
    if len(la) != len(lb):
        return f"{len(la)} vs {len(lb)} lines"
    for x, y in zip(la, lb):
        if x == y:
            continue
        if NUM.sub("#", x) != NUM.sub("#", y):
            return f"line differs:\n  {x}\n  {y}"
        for u, v in zip(NUM.findall(x), NUM.findall(y)):
            if not close(float(u), float(v), 1e-9):
                return f"number differs:\n  {x}\n  {y}"
    return None


def cmp_json(a, b, path: str = "$") -> str | None:
    if isinstance(a, dict) and isinstance(b, dict):
        if a.keys() != b.keys():
            return f"{path}: keys {sorted(set(a) ^ set(b))}"
        return next((e for k in a if (e := cmp_json(a[k], b[k], f"{path}.{k}"))), None)
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            return f"{path}: len {len(a)} vs {len(b)}"
        return next((e for i, (x, y) in enumerate(zip(a, b)) if (e := cmp_json(x, y, f"{path}[{i}]"))), None)
    if isinstance(a, float) or isinstance(b, float):
        if isinstance(a, (int, float)) and isinstance(b, (int, float)) and close(float(a), float(b)):
            return None
        return f"{path}: {a} vs {b}"
    return None if a == b else f"{path}: {a!r} vs {b!r}"


def compare(A: str, B: str) -> int:
    import numpy as np

    bad = 0
    for da in sorted(Path(A).iterdir()):
        db = Path(B) / da.name
        if not db.exists():
            print("MISSING", da.name)
            bad += 1
            continue
        fa = sorted(p.relative_to(da) for p in da.rglob("*") if p.is_file())
        fb = sorted(p.relative_to(db) for p in db.rglob("*") if p.is_file())
        if fa != fb:
            print("FILES", da.name, set(fa) ^ set(fb))
            bad += 1
            continue
        for f in fa:
            x, y = (da / f).read_bytes(), (db / f).read_bytes()
            if x == y:
                continue
            if f.suffix == ".json" or (f.name == "stdout" and x.startswith(b"{")):
                err = cmp_json(json.loads(x), json.loads(y))
            elif f.suffix == ".npy":
                u, v = np.load(da / f), np.load(db / f)
                err = None if u.shape == v.shape and np.allclose(u, v, rtol=1e-12, atol=1e-300) else "npy differs"
            elif f.name in ("stdout", "stderr") or f.suffix == ".csv":
                err = cmp_text(x.decode(), y.decode())
            else:
                err = "bytes differ"
            if err:
                print("DIFF", da.name, f, err)
                bad += 1
    print("compared", len(list(Path(A).iterdir())), "runs;", bad, "differences")
    return bad


if __name__ == "__main__":
    if sys.argv[1] == "--compare":
        sys.exit(1 if compare(sys.argv[2], sys.argv[3]) else 0)
    run(os.path.abspath(sys.argv[1]), os.path.abspath(sys.argv[2]))
