"""acl track: synthetic microscope videos of a known trajectory, tracked to within 0.05 px RMS.

The videos (acl.bench.render): a capsule-like disc (bright interior, dark rim, soft edge) of radius
12 px on an unevenly lit, textured background, motion-blurred, drifting 0.8 px/s right and 0.5 px/s
up on a 3 px circle per second, a flickering lamp (3 %), Gaussian noise at 30 dB SNR (disc contrast
60 grey levels / noise sigma 1.9).  The truth of frame i is the centre of its motion-blurred disc.
"""
from __future__ import annotations

import os

import numpy as np
import pytest

from acl.cli import main

N, FPS, W, H = 60, 30.0, 128, 128
ORIGIN = (60.3, 64.7)
ROI = (40, 44, 40, 40)


@pytest.fixture(scope="module")
def movie():
    from acl.bench.render import blur_centre, render, trajectory

    x, y = trajectory(N, FPS, radius_px=3.0, period_s=1.0)
    frames = render(x, y, W, H, origin=ORIGIN, snr_db=30.0)
    tx, ty = blur_centre(x, y)
    return frames, tx - tx[0], ty - ty[0]


def _write_video(path, frames, codec, params=(), pix="gray"):
    ffmpeg = pytest.importorskip("imageio_ffmpeg")
    w = ffmpeg.write_frames(str(path), (W, H), pix_fmt_in="gray", pix_fmt_out=pix, codec=codec, fps=FPS,
                            macro_block_size=1, output_params=list(params), quality=None)
    w.send(None)
    for f in frames:
        w.send(np.ascontiguousarray(f))
    w.close()


def _write_tiff(path, frames, fps=None):
    tifffile = pytest.importorskip("tifffile")
    meta = {"axes": "TYX", **({"finterval": 1.0 / fps} if fps else {})}
    tifffile.imwrite(str(path), frames, imagej=True, metadata=meta)


def _read_csv(path):
    rows = [r.split(",") for r in open(path).read().splitlines() if r and not r.startswith("#")]
    assert rows[0] == ["observable", "value", "unit", "drive", "time", "sigma"]
    xs = [r for r in rows[1:] if r[0] == "capsule_x"]
    ys = [r for r in rows[1:] if r[0] == "capsule_y"]
    t = np.array([float(r[4]) for r in xs])
    return t, np.array([float(r[1]) for r in xs]), np.array([float(r[1]) for r in ys]), \
        np.array([float(r[5]) for r in xs])


@pytest.mark.parametrize("kind", ["avi", "mp4", "mp4-lossy", "tif"])
def test_tracks_within_0_05_px(movie, tmp_path, kind, capsys):
    """AVI (FFV1, lossless), MP4 (H.264 gray at -qp 0: lossless) and a TIFF stack: RMS error < 0.05 px in x and y
    (measured: about 0.01 px), time from the frame rate, sigma within a factor 3 of the actual error.
    A lossy MP4 (H.264, crf 18, yuv420p) also stays under 0.05 px, but its sigma understates the error
    (the codec's errors follow the picture, not the noise): not compared."""
    frames, tx, ty = movie
    video = tmp_path / f"v.{kind.split('-')[0]}"
    if kind == "avi":
        _write_video(video, frames, "ffv1")
    elif kind == "mp4":
        _write_video(video, frames, "libx264", ["-qp", "0"])
    elif kind == "mp4-lossy":
        _write_video(video, frames, "libx264", ["-crf", "18"], pix="yuv420p")
    else:
        _write_tiff(video, frames, FPS)
    out = tmp_path / "track.csv"
    scale = 0.65
    assert main(["track", str(video), "-o", str(out), "--scale", str(scale),
                 "--roi", ",".join(map(str, ROI)), "-q"]) == 0
    t, x, y, sig = _read_csv(out)
    assert len(t) == N and np.allclose(t, np.arange(N) / FPS, atol=1e-6)
    ex, ey = x / scale - tx, y / scale - ty
    rms_x, rms_y = np.sqrt(np.mean(ex ** 2)), np.sqrt(np.mean(ey ** 2))
    assert rms_x < 0.05 and rms_y < 0.05, (rms_x, rms_y)
    assert np.ptp(tx) > 5             # the disc really moved (circle 6 px across plus drift)
    if kind != "mp4-lossy":
        s = np.median(sig) / scale
        assert s / 3 < max(rms_x, rms_y) < 3 * s * np.sqrt(2), (s, rms_x, rms_y)


def test_tiff_without_frame_rate_needs_fps(movie, tmp_path, capsys):
    frames, tx, ty = movie
    video = tmp_path / "stack.tif"
    _write_tiff(video, frames[:5])
    out = tmp_path / "o.csv"
    assert main(["track", str(video), "-o", str(out), "--scale", "1", "--roi", "40,44,40,40"]) == 2
    err = capsys.readouterr().err
    assert "<--fps>:1:1: error[E-TRACK-FPS]" in err and not out.exists()
    assert main(["track", str(video), "-o", str(out), "--scale", "1", "--roi", "40,44,40,40", "--fps", "200",
                 "--name", "module", "-q"]) == 0
    rows = out.read_text().splitlines()
    assert rows[2].startswith("module_x,0,um,,0,") and rows[-1].startswith("module_y,") and ",0.02," in rows[-1]


def test_tracked_csv_reads_as_fit_data(movie, tmp_path):
    """The CSV is the data format `acl fit` reads (acl.fit.data.read_data on a design observing
    module_x and module_y)."""
    from acl.fit.data import read_data
    import acl

    frames, _, _ = movie
    video = tmp_path / "stack.tif"
    _write_tiff(video, frames[:4], FPS)
    out = tmp_path / "o.csv"
    assert main(["track", str(video), "-o", str(out), "--scale", "0.5", "--roi", "40,44,40,40",
                 "--name", "module", "-q"]) == 0
    here = os.path.dirname(__file__)
    design_text = open(os.path.join(here, "test_compile_cli.py")).read().split('DESIGN = """\\\n', 1)[1].split('"""', 1)[0]
    design_text += "observe module_x = displacement(module, +x)\nobserve module_y = displacement(module, +y)\n"
    d = tmp_path / "d.acl"
    d.write_text(design_text)
    data = read_data([str(out)], acl.load(str(d)))
    assert data.n == 8 and set(data.observable) == {"module_x", "module_y"}


# -- bad input: located, coded, exit 2, no traceback, no output file ----------------------------------

def _bad(tmp_path, capsys, argv, code, where):
    out = tmp_path / "o.csv"
    assert main(["track", *argv, "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"{where}: error[{code}]" in err and "Traceback" not in err, err
    assert not out.exists() and not [p for p in os.listdir(tmp_path) if p.startswith(".acl-")]


def test_unreadable_videos(tmp_path, capsys):
    pytest.importorskip("imageio_ffmpeg")
    pytest.importorskip("tifffile")
    missing = tmp_path / "none.avi"
    _bad(tmp_path, capsys, [str(missing), "--scale", "1"], "E-TRACK-VIDEO", f"{missing}:1:1")
    junk = tmp_path / "junk.mp4"
    junk.write_bytes(b"\x00not a video at all" * 50)
    _bad(tmp_path, capsys, [str(junk), "--scale", "1"], "E-TRACK-VIDEO", f"{junk}:1:1")
    tif = tmp_path / "junk.tif"
    tif.write_bytes(b"II*\x00garbage")
    _bad(tmp_path, capsys, [str(tif), "--scale", "1"], "E-TRACK-VIDEO", f"{tif}:1:1")
    txt = tmp_path / "notes.txt"
    txt.write_text("hello")
    _bad(tmp_path, capsys, [str(txt), "--scale", "1"], "E-TRACK-VIDEO", f"{txt}:1:1")
    _bad(tmp_path, capsys, [str(tmp_path), "--scale", "1"], "E-TRACK-VIDEO", f"{tmp_path}:1:1")


@pytest.mark.parametrize("opts,code,where", [
    (["--scale", "0"], "E-TRACK-SCALE", "<--scale>:1:1"),
    (["--scale", "nan"], "E-TRACK-SCALE", "<--scale>:1:1"),
    (["--scale", "um"], "E-TRACK-SCALE", "<--scale>:1:1"),
    (["--scale", "1", "--roi", "1,2,3"], "E-TRACK-ROI", "<--roi>:1:1"),
    (["--scale", "1", "--roi", "a,b,c,d"], "E-TRACK-ROI", "<--roi>:1:1"),
    (["--scale", "1", "--roi", "100,100,64,64"], "E-TRACK-ROI", "<--roi>:1:1"),     # beyond the 128x128 frame
    (["--scale", "1", "--roi", "0,0,4,4"], "E-TRACK-ROI", "<--roi>:1:1"),
    (["--scale", "1", "--fps", "-3"], "E-TRACK-FPS", "<--fps>:1:1"),
])
def test_bad_options(movie, tmp_path, capsys, opts, code, where):
    frames, _, _ = movie
    video = tmp_path / "v.tif"
    _write_tiff(video, frames[:3], FPS)
    _bad(tmp_path, capsys, [str(video), *opts], code, where)


def test_output_not_a_regular_file(movie, tmp_path, capsys):
    frames, _, _ = movie
    video = tmp_path / "v.tif"
    _write_tiff(video, frames[:3], FPS)
    fifo = tmp_path / "pipe.csv"
    os.mkfifo(fifo)
    assert main(["track", str(video), "-o", str(fifo), "--scale", "1"]) == 2
    assert "<--output>:1:1: error[E-TRACK-OUTPUT]" in capsys.readouterr().err
    assert main(["track", str(video), "-o", str(tmp_path), "--scale", "1"]) == 2
    assert "E-TRACK-OUTPUT" in capsys.readouterr().err
