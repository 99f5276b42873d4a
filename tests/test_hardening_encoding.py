"""A file that is not UTF-8 is located at its first bad byte (line and character column) by every reader:
designs, standard input, data files (acl fit), calibration sweeps (acl compile --calibration), schedules
(acl synth --schedule), lint configurations; with a byte-order mark too (the readers decode with
``utf-8-sig``, whose error offsets start after the mark: they named the byte 3 places early)."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from acl.cli import main
from acl.diagnostics import DiagnosticError

ROOT = Path(__file__).resolve().parents[1]
CANTILEVER = str(ROOT / "samples" / "fit_cantilever.acl")
BOM = b"\xef\xbb\xbf"


@pytest.mark.parametrize("bom", [b"", BOM], ids=["plain", "bom"])
def test_data_file_byte_is_located_with_and_without_a_byte_order_mark(tmp_path, capsys, bom):
    path = tmp_path / "d.csv"
    path.write_bytes(bom + b"observable,value,unit,drive,time,sigma\ndeflection,1.0,\xb5m,125 kHz @ 2 V,1,0.05\n")
    assert main(["fit", CANTILEVER, str(path), "--free", "gamma"]) == 1
    err = capsys.readouterr().err
    # with a BOM this said `byte 0x2e` (the `.` of 1.0) at column 13
    assert f"{path}:2:16: error[E807]: data file is not UTF-8 text: byte 0xb5" in err, err


@pytest.mark.parametrize("bom", [b"", BOM], ids=["plain", "bom"])
def test_calibration_byte_is_located_with_and_without_a_byte_order_mark(tmp_path, bom):
    from acl.schedule.calibration import read_sweep_csv

    path = tmp_path / "c.csv"
    path.write_bytes(bom + b"frequency [kHz],dx [um],dy [um]\n# voltage: 5 V \xb5\n110,0.1,0\n")
    with pytest.raises(DiagnosticError) as exc:
        read_sweep_csv(str(path))
    d = exc.value.diagnostics[0]
    assert (d.code, d.span.line, d.span.column) == ("E-CSV-READ", 2, 16) and "0xb5" in d.message, (str(d.span), d.message)


@pytest.mark.parametrize("bom", [b"", BOM], ids=["plain", "bom"])
def test_schedule_byte_is_located_with_and_without_a_byte_order_mark(tmp_path, capsys, bom):
    path = tmp_path / "s.json"
    path.write_bytes(bom + b'{"version": "1.1",\n "program": "caf\xe9", "segments": []}\n')
    out = tmp_path / "r.csv"
    assert main(["synth", CANTILEVER, "--schedule", str(path), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"{path}:2:17: error[E-SYNTH-SCHEDULE]: not UTF-8 text (byte 0xe9)" in err, err
    assert not out.exists()


@pytest.mark.parametrize("bom", [b"", BOM], ids=["plain", "bom"])
def test_design_byte_is_located_not_at_line_1(tmp_path, capsys, bom):
    """Was `d.acl:1:1: error[E103]: cannot read ...: not UTF-8 text (byte 714)`, the caret under line 1."""
    path = tmp_path / "d.acl"
    path.write_bytes(bom + Path(CANTILEVER).read_bytes() + b"# 5 \xb5m\n")
    n = Path(CANTILEVER).read_text().count("\n") + 1
    assert main(["check", str(path)]) == 1
    err = capsys.readouterr().err
    assert f"{path}:{n}:5: error[E103]" in err and "byte 0xb5" in err, err


def test_design_on_standard_input_is_located_at_its_byte():
    r = subprocess.run([sys.executable, "-m", "acl", "check", "-"], input=b"param a = 1\nparam b = 2 # \xb5m\n",
                       capture_output=True, cwd=ROOT, timeout=120)
    err = r.stderr.decode()
    assert r.returncode != 0 and "Traceback" not in err
    assert "<stdin>:2:15: error[E103]" in err and "byte 0xb5" in err, err
