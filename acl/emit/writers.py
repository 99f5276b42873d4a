"""Streaming waveform writers: WAV (float32 IEEE), NPY (float32 volts), CSV (time, volts).

Each writer knows the total sample count up front (the schedule fixes it), writes its header
first and then appends chunks, so memory never depends on duration.

WAV scale: a sample is ``volts / full_scale_v`` (so +-1.0 is the full-scale voltage recorded in
schedule.json, fixed with ``acl compile --full-scale``); format tag 3 (IEEE float), 32 bits,
mono, with the ``fact`` chunk non-PCM formats require.  NPY and CSV hold volts; the CSV
(``waveform-samples.csv``) has one row per sample, about 24 bytes each.
"""
from __future__ import annotations

import struct

import numpy as np

FORMATS = ("wav", "csv", "npy", "seq")     # seq: no samples, acl/emit/seq.py


class WavWriter:
    def __init__(self, path: str, n_samples: int, sample_rate: float, full_scale_v: float):
        if int(sample_rate) != sample_rate or not 0 < sample_rate < 2 ** 32:
            raise ValueError("a WAV sample rate must be a positive integer below 2^32 Hz")
        data_bytes = 4 * n_samples
        if 4 + 26 + 12 + 8 + data_bytes >= 2 ** 32:
            raise ValueError("waveform too long for a WAV file (4 GiB); use npy")
        self.scale = 1.0 / full_scale_v
        self.fh = open(path, "wb")
        fs = int(sample_rate)
        fmt = struct.pack("<HHIIHHH", 3, 1, fs, fs * 4, 4, 32, 0)          # cbSize = 0
        self.fh.write(b"RIFF" + struct.pack("<I", 4 + (8 + len(fmt)) + 12 + 8 + data_bytes) + b"WAVE")
        self.fh.write(b"fmt " + struct.pack("<I", len(fmt)) + fmt)
        self.fh.write(b"fact" + struct.pack("<II", 4, n_samples))
        self.fh.write(b"data" + struct.pack("<I", data_bytes))

    def write(self, n0: int, volts: np.ndarray) -> None:
        (volts * self.scale).astype("<f4").tofile(self.fh)

    def close(self) -> None:
        self.fh.close()


class NpyWriter:
    def __init__(self, path: str, n_samples: int, sample_rate: float, full_scale_v: float):
        self.fh = open(path, "wb")
        np.lib.format.write_array_header_1_0(
            self.fh, {"descr": "<f4", "fortran_order": False, "shape": (n_samples,)})

    def write(self, n0: int, volts: np.ndarray) -> None:
        volts.astype("<f4").tofile(self.fh)

    def close(self) -> None:
        self.fh.close()


class CsvWriter:
    def __init__(self, path: str, n_samples: int, sample_rate: float, full_scale_v: float):
        self.fs = float(sample_rate)
        self.fh = open(path, "w", encoding="utf-8", newline="\n")
        self.fh.write("time_s,volts\n")

    def write(self, n0: int, volts: np.ndarray) -> None:
        t = (n0 + np.arange(volts.size)) / self.fs
        np.savetxt(self.fh, np.column_stack([t, volts]), fmt=("%.10g", "%.7g"), delimiter=",")

    def close(self) -> None:
        self.fh.close()


WRITERS = {"wav": (WavWriter, "waveform.wav"), "npy": (NpyWriter, "waveform.npy"),
           "csv": (CsvWriter, "waveform-samples.csv")}
CSV_BYTES_PER_SAMPLE = 24          # "%.10g,%.7g\n": a typical row


def read_wav_float32(path: str) -> tuple[np.ndarray, int]:
    """Read back a float32 WAV written by :class:`WavWriter` (samples, sample rate); for tests/tools."""
    with open(path, "rb") as fh:
        data = fh.read()
    if data[:4] != b"RIFF" or data[8:12] != b"WAVE":
        raise ValueError("not a RIFF/WAVE file")
    pos, fs, fmt_tag, samples = 12, None, None, None
    while pos + 8 <= len(data):
        cid, size = data[pos:pos + 4], struct.unpack("<I", data[pos + 4:pos + 8])[0]
        body = data[pos + 8:pos + 8 + size]
        if cid == b"fmt ":
            fmt_tag, _, fs = struct.unpack("<HHI", body[:8])
        elif cid == b"data":
            samples = np.frombuffer(body, dtype="<f4")
        pos += 8 + size + (size & 1)
    if fmt_tag != 3 or samples is None:
        raise ValueError("not an IEEE-float WAV")
    return samples, fs
