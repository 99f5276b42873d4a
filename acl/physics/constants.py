"""Physical constants and documented defaults of the acoustic models (SI units).

A design normally declares its medium and transducer; these values are used only when the
design leaves them out (the analysis says so in its result).  Every number names its source.
"""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class MediumConstants:
    """Liquid and gas properties used by the bubble models (same fields as acl.design Medium)."""

    density: float = 998.2               # kg/m^3, water 20 C (CRC Handbook)
    viscosity: float = 1.002e-3          # Pa s, water 20 C (CRC Handbook)
    sound_speed: float = 1482.0          # m/s, water 20 C (CRC Handbook)
    surface_tension: float = 0.0728      # N/m, water/air 20 C (CRC Handbook); PBS within 1 %
    ambient_pressure: float = 101325.0   # Pa, standard atmosphere
    # Polytropic index of the trapped air.  1.0 (isothermal): the thermal diffusion length of air
    # at 100 kHz, sqrt(2 D / omega) ~ 7 um, is as large as the cavity's volume-to-wall ratio
    # (~7 um) and the polymer walls are a heat reservoir, so the gas stays near wall temperature;
    # Prosperetti (J. Acoust. Soc. Am. 61, 17 (1977)) gives Re(Phi)/3 ~ 1.1 at this Peclet number.
    # See docs/physics.md (part A) for the check against Table S1 with 1.4.
    polytropic_index: float = 1.0
    gas_thermal_diffusivity: float = 2.1e-5   # m^2/s, air 20 C
    gas_heat_capacity_ratio: float = 1.4      # air; used by the thermal damping model only

    def as_tuple(self) -> tuple[float, ...]:
        return (self.density, self.viscosity, self.sound_speed, self.surface_tension,
                self.ambient_pressure, self.polytropic_index, self.gas_thermal_diffusivity,
                self.gas_heat_capacity_ratio)


WATER_20C = MediumConstants()

#: Flat transducer gain used when a design declares no transducer (Pa per V peak).  The paper does
#: not print its Fig. S1 / Fig. 2e values.  100 Pa/V keeps Design 1's interface centre amplitude
#: (about 2 nm/Pa at resonance in this model) below R/2 at the ~20 V the paper drives with (Table S2
#: via Eq. 3), i.e. inside the linear regime of Fig. 2f.  Order of magnitude only; NOT fitted to
#: gamma (the gain that would reproduce gamma = 0.027 nN/V^2 is reported in the docs).
DEFAULT_GAIN_PA_PER_V = 100.0

#: Dimensionless streaming constant C_s in F = C_s rho (omega eps)^2 pi R^2 (thrust of the jet
#: of one orifice; eps the centre amplitude of the interface).  Calibrated once from the measured
#: critical distance of two facing identical Design-1 capsules (d_c = 50 um, paper text at Fig. 4):
#: with the free-field Bjerknes force rho w^2 |dV|^2/(8 pi d^2) and 2 F_thrust pushing apart,
#: d_c = R / (8 sqrt(C_s)), so C_s = (10 um / (8 * 50 um))^2.  The naive rectified momentum
#: flux (C_s = 1/2) would put d_c at 1.8 um, contradicting Fig. 4 (docs/physics.md (part A)).
STREAMING_CONSTANT = (10e-6 / (8 * 50e-6)) ** 2

#: Number of axisymmetric membrane shapes per interface in the Rayleigh-Ritz model: the first
#: frequency at 3 shapes is within 0.001 % of 8 shapes over the Fig. 1e range
#: (tests/test_physics_resonance.py checks 0.2 %).
DEFAULT_MEMBRANE_MODES = 3
