"""Sub-pixel tracking of one template through a microscope video (`acl track`).

Reading: AVI/MP4 through ffmpeg (imageio-ffmpeg, decoded straight to 8-bit gray) and multi-page
TIFF stacks (tifffile).  Registration: the template (the first frame's ``--roi``, or the whole first
frame) is found in each frame by a coarse phase correlation (whole pixels) and then a Gauss-Newton
(Lucas-Kanade) fit of the shift with cubic-spline interpolation of the frame, in the model

    frame(p + s) = a * template(p) + b + c * x + d * y

(a, b: the frame's gain and offset; c, d: an illumination gradient: a static, unevenly lit background
under a moving template shifts by a constant and a tilt, which the model absorbs).  The fit's
covariance, residual variance x (J^T J)^-1, gives each row's standard uncertainty (``sigma``).
Positions are the template's displacement since the first frame, in pixels, x right, y down.
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass

import numpy as np

from acl.diagnostics import DiagnosticError, Span, error

VIDEO_EXT = {".avi", ".mp4", ".mov", ".mkv", ".m4v"}
TIFF_EXT = {".tif", ".tiff"}
MAX_FRAMES = 1_000_000


def _fail(code, message, where, hint=None):
    raise DiagnosticError([error(code, message, Span(file=where, line=1, column=1), hint)])


@dataclass
class Video:
    frames: object          # iterator of 2-D float32 arrays
    fps: float | None
    width: int
    height: int


def open_video(path: str) -> Video:
    """The frames of ``path`` (gray, float32) and its frame rate (None for a TIFF without one).
    E-TRACK-VIDEO when it cannot be read (missing, not a file, not a video or stack, empty)."""
    hint = "give an AVI or MP4 video, or a multi-page TIFF stack"
    if not os.path.exists(path):
        _fail("E-TRACK-VIDEO", f"cannot read {path!r}: no such file", path, hint)
    if not os.path.isfile(path):
        _fail("E-TRACK-VIDEO", f"cannot read {path!r}: not a regular file", path, hint)
    ext = os.path.splitext(path)[1].lower()
    if ext in TIFF_EXT:
        return _open_tiff(path)
    if ext in VIDEO_EXT:
        return _open_ffmpeg(path)
    _fail("E-TRACK-VIDEO", f"{path!r}: unknown video type {ext or '(no extension)'!r}", path,
          "AVI, MP4, MOV, MKV (through ffmpeg) or TIF/TIFF stacks")


def _open_tiff(path: str) -> Video:
    try:
        import tifffile
    except ImportError:
        _fail("E-TRACK-VIDEO", "reading TIFF stacks needs tifffile: pip install 'acl[bench]' (from a checkout: pip install '.[bench]')", path)
    try:
        tif = tifffile.TiffFile(path)
        pages = tif.pages
        first = pages[0].asarray()
    except Exception as exc:       # tifffile raises TiffFileError, ValueError, struct errors ... on a bad file
        _fail("E-TRACK-VIDEO", f"cannot read {path!r} as a TIFF stack: {str(exc).splitlines()[0] if str(exc) else type(exc).__name__}",
              path, "give a multi-page TIFF stack")
    if first.ndim == 3:
        first = first.mean(axis=2) if first.shape[2] in (3, 4) else first[0]
    if first.ndim != 2 or first.size == 0:
        _fail("E-TRACK-VIDEO", f"{path!r}: the first page is not a 2-D image", path)
    fps = None
    ij = tif.imagej_metadata or {}
    if ij.get("finterval"):
        try:
            fps = 1.0 / float(ij["finterval"])
        except (TypeError, ValueError, ZeroDivisionError):
            fps = None
    elif ij.get("fps"):
        fps = float(ij["fps"])
    n_pages = len(pages)
    shape = first.shape

    def frames():
        try:
            if n_pages == 1 and tif.series and len(tif.series[0].shape) >= 3:
                stack = tif.series[0].asarray()
                for f in stack.reshape(-1, *stack.shape[-2:]):
                    yield f.astype(np.float32)
                return
            for i in range(n_pages):
                a = pages[i].asarray()
                if a.ndim == 3:
                    a = a.mean(axis=2) if a.shape[2] in (3, 4) else a[0]
                if a.shape != shape:
                    _fail("E-TRACK-VIDEO", f"{path!r}: page {i + 1} is {a.shape[1]}x{a.shape[0]}, the first "
                          f"{shape[1]}x{shape[0]}", path)
                yield a.astype(np.float32)
        except DiagnosticError:
            raise
        except Exception as exc:
            _fail("E-TRACK-VIDEO", f"{path!r}: a page cannot be read: {str(exc).splitlines()[0] if str(exc) else type(exc).__name__}",
                  path)
        finally:
            tif.close()

    return Video(frames(), fps, shape[1], shape[0])


def _open_ffmpeg(path: str) -> Video:
    try:
        import imageio_ffmpeg
    except ImportError:
        _fail("E-TRACK-VIDEO", "reading AVI/MP4 needs imageio-ffmpeg: pip install 'acl[bench]' (from a checkout: pip install '.[bench]')", path)
    try:
        gen = imageio_ffmpeg.read_frames(path, pix_fmt="gray", bits_per_pixel=8)
        meta = next(gen)
        w, h = (int(x) for x in meta["size"])
        fps = float(meta.get("fps") or 0) or None
    except Exception as exc:      # imageio-ffmpeg raises IOError/RuntimeError with ffmpeg's message
        msg = str(exc).strip().splitlines()
        _fail("E-TRACK-VIDEO", f"cannot read {path!r} as a video: {msg[-1][:200] if msg else type(exc).__name__}",
              path, "is it an AVI or MP4 file ffmpeg can decode?")
    if w <= 0 or h <= 0:
        _fail("E-TRACK-VIDEO", f"{path!r}: the video has no picture", path)

    def frames():
        try:
            for raw in gen:
                yield np.frombuffer(raw, dtype=np.uint8).reshape(h, w).astype(np.float32)
        except Exception as exc:
            _fail("E-TRACK-VIDEO", f"{path!r}: decoding stopped: {str(exc).strip().splitlines()[-1][:200] if str(exc).strip() else type(exc).__name__}",
                  path)
        finally:
            gen.close()

    return Video(frames(), fps, w, h)


class Tracker:
    """Finds the template ``first[y:y+h, x:x+w]`` in later frames to a small fraction of a pixel."""

    def __init__(self, first: np.ndarray, roi: tuple[int, int, int, int], margin: int = 8,
                 iterations: int = 12):
        x, y, w, h = roi
        self.roi = roi
        self.margin = margin
        self.iterations = iterations
        t = first[y:y + h, x:x + w].astype(np.float64)
        self.template = t
        gy, gx = np.gradient(t)
        yy, xx = np.mgrid[0:h, 0:w].astype(np.float64)
        self.grid = (yy.ravel(), xx.ravel())
        xc, yc = xx - xx.mean(), yy - yy.mean()
        # columns: -dT/dx, -dT/dy (times a), T, 1, x, y   (constant: the template's, not the frame's gradient)
        A = np.column_stack([-gx.ravel(), -gy.ravel(), t.ravel(), np.ones(t.size), xc.ravel(), yc.ravel()])
        self.A = A
        self.AtA_inv = np.linalg.inv(A.T @ A)
        self.pinv = self.AtA_inv @ A.T
        self.shift = np.zeros(2)           # (sx, sy) pixels
        # coarse search: the template's spectrum in a window `margin` larger on each side
        self.win = (h + 2 * margin, w + 2 * margin)
        pad = np.zeros(self.win)
        pad[margin:margin + h, margin:margin + w] = t - t.mean()
        self.tf = np.conj(np.fft.rfft2(pad))

    def _window(self, frame, cx, cy):
        """The frame around the template's current place (edge pixels repeated outside the frame)."""
        x, y, w, h = self.roi
        m = self.margin
        H, W = frame.shape
        y0, x0 = y + cy - m, x + cx - m
        ys = np.clip(np.arange(y0, y0 + h + 2 * m), 0, H - 1)
        xs = np.clip(np.arange(x0, x0 + w + 2 * m), 0, W - 1)
        return frame[np.ix_(ys, xs)].astype(np.float64)

    def _coarse(self, frame) -> None:
        """Whole-pixel correction of the shift by cross-correlation in the search window."""
        cx, cy = (int(round(v)) for v in self.shift)
        win = self._window(frame, cx, cy)
        c = np.fft.irfft2(np.fft.rfft2(win - win.mean()) * self.tf, s=self.win)
        iy, ix = np.unravel_index(int(np.argmax(c)), c.shape)
        hy, hx = self.win
        dy = iy if iy <= hy // 2 else iy - hy
        dx = ix if ix <= hx // 2 else ix - hx
        if (dx or dy) and abs(dx) <= self.margin and abs(dy) <= self.margin:
            self.shift = self.shift + np.array([dx, dy], dtype=float)

    def track(self, frame: np.ndarray) -> tuple[float, float, float, float, bool]:
        """(sx, sy, sigma_x, sigma_y, converged): the template's shift since the first frame."""
        from scipy.ndimage import map_coordinates

        self._coarse(frame)
        x, y, w, h = self.roi
        m = self.margin + 3
        cx, cy = (int(round(v)) for v in self.shift)
        H, W = frame.shape
        y0, x0 = y + cy - m, x + cx - m
        ys = np.clip(np.arange(y0, y0 + h + 2 * m), 0, H - 1)
        xs = np.clip(np.arange(x0, x0 + w + 2 * m), 0, W - 1)
        win = frame[np.ix_(ys, xs)].astype(np.float64)
        from scipy.ndimage import spline_filter

        coef = spline_filter(win, order=3, mode="nearest")
        gy, gx = self.grid
        converged = False
        theta = None
        r = None
        for _ in range(self.iterations):
            py = gy + (self.shift[1] - cy) + m
            px = gx + (self.shift[0] - cx) + m
            sample = map_coordinates(coef, (py, px), order=3, prefilter=False, mode="nearest")
            theta = self.pinv @ sample
            a = theta[2] if abs(theta[2]) > 1e-6 else 1e-6
            d = theta[:2] / a
            d = np.clip(d, -1.0, 1.0)
            self.shift = self.shift + d
            if np.hypot(*d) < 1e-4:
                converged = True
                break
        py = gy + (self.shift[1] - cy) + m
        px = gx + (self.shift[0] - cx) + m
        sample = map_coordinates(coef, (py, px), order=3, prefilter=False, mode="nearest")
        theta = self.pinv @ sample
        r = sample - self.A @ theta
        var = float(r @ r) / max(1, r.size - 6)
        a = abs(theta[2]) if abs(theta[2]) > 1e-6 else 1e-6
        cov = var * self.AtA_inv
        sx = math.sqrt(max(cov[0, 0], 0.0)) / a
        sy = math.sqrt(max(cov[1, 1], 0.0)) / a
        return float(self.shift[0]), float(self.shift[1]), sx, sy, converged


@dataclass
class Track:
    time: np.ndarray        # s since the first frame
    x: np.ndarray           # px, displacement since the first frame, right
    y: np.ndarray           # px, down
    sigma_x: np.ndarray
    sigma_y: np.ndarray
    roi: tuple[int, int, int, int]
    fps: float
    lost: int = 0           # frames whose fit did not converge


def check_roi(roi, width: int, height: int, where: str = "<--roi>"):
    """The ROI inside the frame and at least 8x8 pixels (E-TRACK-ROI otherwise)."""
    x, y, w, h = roi
    if w < 8 or h < 8 or x < 0 or y < 0 or x + w > width or y + h > height:
        _fail("E-TRACK-ROI", f"--roi {x},{y},{w},{h} is not inside the {width}x{height} frame or smaller than "
              "8x8 pixels", where, f"X,Y,W,H with X+W <= {width}, Y+H <= {height}, W and H >= 8")


def track_video(path: str, roi: tuple[int, int, int, int] | None = None, fps: float | None = None,
                margin: int = 8) -> Track:
    """Track the template through the video at ``path`` (DiagnosticError on bad input)."""
    video = open_video(path)
    rate = video.fps if video.fps else fps
    if fps is not None:
        rate = fps if not video.fps else video.fps
    if not rate:
        _fail("E-TRACK-FPS", f"{path!r} records no frame rate", "<--fps>", "give --fps F (frames per second)")
    if roi is None:
        roi = (0, 0, video.width, video.height)
    check_roi(roi, video.width, video.height)
    tracker = None
    out = []
    lost = 0
    for i, frame in enumerate(video.frames):
        if frame.shape != (video.height, video.width):
            _fail("E-TRACK-VIDEO", f"{path!r}: frame {i + 1} changes size", path)
        if i >= MAX_FRAMES:
            _fail("E-TRACK-VIDEO", f"{path!r}: more than {MAX_FRAMES:,} frames", path, "cut the video")
        if tracker is None:
            tracker = Tracker(frame, roi, margin=margin)
        sx, sy, ex, ey, ok = tracker.track(frame)
        lost += not ok
        out.append((i / rate, sx, sy, ex, ey))
    if not out:
        _fail("E-TRACK-VIDEO", f"{path!r} holds no frames", path)
    a = np.array(out)
    if len(a) > 1:      # frame 0 is the template (shift 0, no residual): its noise is in every other frame's sigma
        a[0, 3], a[0, 4] = np.median(a[1:, 3]), np.median(a[1:, 4])
    return Track(a[:, 0], a[:, 1], a[:, 2], a[:, 3], a[:, 4], roi, float(rate), lost)


def drive_cells(times, drives, sync_s: float) -> list[str]:
    """The drive playing at each frame (``drive`` cells of docs/data.md): the schedule's segment at
    ``time - sync_s`` (the schedule starts ``sync_s`` seconds into the video); empty outside it or
    in a pause."""
    from acl.fit.drive import format_drive

    starts = np.array([d.start_s for d in drives])
    ends = starts + np.array([d.duration_s for d in drives])
    cells = []
    for t in np.asarray(times) - sync_s + 1e-9:      # a frame on a boundary (to 1 ns) shows the new drive
        k = int(np.searchsorted(starts, t, side="right")) - 1
        if k < 0 or t >= ends[k] or not drives[k].tones:
            cells.append("")
        else:
            cells.append(format_drive([(f, a) for f, a, _ in drives[k].tones]))
    return cells


def csv_text(track: Track, name: str, scale_um: float, source: str, drives: list[str] | None = None) -> str:
    """The data format `acl fit` reads (docs/data.md): rows NAME_x and NAME_y per frame, um."""
    x, y, w, h = track.roi
    lines = [f"# acl track {source}: template {w}x{h} px at ({x}, {y}) px, {scale_um:g} um/px, "
             f"{track.fps:g} frames/s; values are displacements since the first frame (x right, y down)",
             "observable,value,unit,drive,time,sigma"]
    floor = 1e-6            # um: a sigma the fit accepts (it refuses non-positive ones)
    drives = drives or [""] * len(track.time)
    for t, dx, dy, ex, ey, dr in zip(track.time, track.x, track.y, track.sigma_x, track.sigma_y, drives):
        dx, dy = (0.0 if abs(v) < 1e-9 else v for v in (dx, dy))
        lines.append(f"{name}_x,{dx * scale_um:.6g},um,{dr},{t:.9g},{max(ex * scale_um, floor):.3g}")
        lines.append(f"{name}_y,{dy * scale_um:.6g},um,{dr},{t:.9g},{max(ey * scale_um, floor):.3g}")
    return "\n".join(lines) + "\n"
