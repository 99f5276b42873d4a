"""The drive chain between a schedule and the transducer: a signal generator and an amplifier.

Values are datasheet values as transcribed (not measured here); check them against your unit's
datasheet.  The paper's bench (seed paper, Methods, "Experimental Platform") is a GW Instek AFG-2225
function generator into a Thorlabs HVA200 amplifier.
"""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Generator:
    key: str
    name: str
    dialect: str                  # "afg2200" or "33500"
    channels: int
    max_frequency_hz: float       # sine
    max_vpp: float                # into a high-impedance load
    min_vpp: float                # into a high-impedance load
    vpp_digits: int               # decimals of a Vpp setting (resolution 10**-digits V)
    sample_rate_max: float        # arbitrary waveform, samples/s
    memory_points: int            # arbitrary waveform memory per channel
    sequence: bool                # plays a list of looped segments timed by the instrument
    max_sequence_steps: int = 0
    min_segment_points: int = 8
    combine: bool = False         # can add channel 2 into output 1 (one amplifier input)
    source: str = "datasheet"


@dataclass(frozen=True)
class Amplifier:
    key: str
    name: str
    gain: float                   # V/V
    max_output_v: float           # peak
    bandwidth_hz: float           # -3 dB, small signal
    max_input_v: float            # peak
    source: str = "datasheet"


GENERATORS = {
    "afg2225": Generator("afg2225", "GW Instek AFG-2225", "afg2200", channels=2, max_frequency_hz=25e6,
                         max_vpp=20.0, min_vpp=2e-3, vpp_digits=4, sample_rate_max=120e6,
                         memory_points=4096, sequence=False,
                         source="GW Instek AFG-2225 datasheet (2 channels, 25 MHz, 120 MSa/s, 4 k points, "
                                "1 mVpp-10 Vpp into 50 ohm, twice into high impedance)"),
    "33522b": Generator("33522b", "Keysight 33522B", "33500", channels=2, max_frequency_hz=30e6,
                        max_vpp=20.0, min_vpp=2e-3, vpp_digits=4, sample_rate_max=250e6,
                        memory_points=1_000_000, sequence=True, max_sequence_steps=512,
                        min_segment_points=8, combine=True,
                        source="Keysight 33500B series datasheet (33522B: 2 channels, 30 MHz, 250 MSa/s, "
                               "1 MSa per channel, sequencing, channel combine)"),
}

AMPLIFIERS = {
    "hva200": Amplifier("hva200", "Thorlabs HVA200", gain=20.0, max_output_v=200.0, bandwidth_hz=1e6,
                        max_input_v=10.0,
                        source="Thorlabs HVA200 datasheet (gain 20 V/V, +-200 V, 1 MHz)"),
    "none": Amplifier("none", "no amplifier (generator into the transducer)", gain=1.0, max_output_v=10.0,
                      bandwidth_hz=float("inf"), max_input_v=10.0, source="-"),
}
