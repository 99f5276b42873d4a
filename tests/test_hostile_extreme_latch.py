"""Issue 28: `acl analyze` of Fig. 6e's latch with a value of 1e308 exited 0 with a Python warning on
stderr.  Every number of the latch and its placement, set to 1e308 (and 1e-308) in its unit, gives a
result or a located diagnostic: never a Python warning, traceback or E-INTERNAL.  All cases run in
one Python process with every warning shown (`-W always`), as a user's shell would see them."""
from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FIG6E = ROOT / "examples" / "fig6e_reversible_latch.acl"

_RUN = r'''
import json, sys
from acl.cli import main
for path, extra in json.loads(sys.argv[1]):
    sys.stderr.write(f"=== {path} {extra}\n")
    sys.stderr.flush()
    try:
        code = main(["analyze", path, *extra])
    except SystemExit as exc:
        code = exc.code
    sys.stderr.write(f"=== exit {code}\n")
'''


def _cases(tmp_path):
    lines = FIG6E.read_text(encoding="utf-8").split("\n")
    start = next(i for i, line in enumerate(lines) if line.startswith("latch l {"))
    end = next(i for i in range(start, len(lines)) if lines[i].startswith("}"))
    targets = [i for i in range(start, end) if re.search(r"\d", lines[i].split("#")[0])]
    targets.append(next(i for i, line in enumerate(lines) if line.startswith("param z =")))
    out = []
    for i in targets:
        code = lines[i].split("#")[0]
        for m in re.finditer(r"(?<![\w.])\d+(\.\d+)?(?=\s*(um|deg|kHz|V)\b)", code):
            for v in ("1e308", "1e-308"):
                new = list(lines)
                new[i] = lines[i][:m.start()] + v + lines[i][m.end():]
                p = tmp_path / f"l{i}_{m.start()}_{v}.acl"
                p.write_text("\n".join(new), encoding="utf-8")
                out += [(str(p), []), (str(p), ["--at", "85 kHz @ 6 V"])]
    return out


def test_extreme_latch_values_never_print_a_python_warning(tmp_path):
    cases = _cases(tmp_path)
    assert len(cases) >= 20
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep)}
    r = subprocess.run([sys.executable, "-W", "always", "-c", _RUN, json.dumps(cases)], capture_output=True, text=True,
                       env=env, cwd=tmp_path, timeout=600)
    bad = [line for line in r.stderr.splitlines() if re.search(r"Warning\b|Traceback|E-INTERNAL", line)]
    assert not bad, bad[:5]
    exits = re.findall(r"=== exit (\S+)", r.stderr)
    assert len(exits) == len(cases) and set(exits) <= {"0", "1", "2"}
    assert "1" in exits                              # refused with a located error (E412, E414, ...)
