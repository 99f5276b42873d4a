"""Quantities and dimensions at the edge; SI floats past it.

Unit strings are parsed by pint (its registry cached on disk so start-up stays low) and memoised;
arithmetic during evaluation uses :class:`Quantity`, an SI float with a dimension vector, which is
~100x faster than pint objects and all the resolver needs.
"""
from __future__ import annotations

import functools
import math
import os
import re
from dataclasses import dataclass

# Dimension vector order: length, mass, time, current, temperature, amount, luminosity.
_BASE = ("[length]", "[mass]", "[time]", "[current]", "[temperature]", "[substance]", "[luminosity]")
_SYMBOL = ("m", "kg", "s", "A", "K", "mol", "cd")

Dims = tuple[int, int, int, int, int, int, int]
DIMENSIONLESS: Dims = (0, 0, 0, 0, 0, 0, 0)


class UnitError(ValueError):
    """A unit string pint does not know, with a hint."""

    def __init__(self, message: str, hint: str | None = None):
        super().__init__(message)
        self.hint = hint


@functools.lru_cache(maxsize=1)
def registry():
    import pint

    cache = os.path.join(_cache_dir(), "pint")
    try:
        os.makedirs(cache, exist_ok=True)
        return pint.UnitRegistry(cache_folder=cache)
    except Exception:  # read-only home: no cache, still correct
        return pint.UnitRegistry()


_ALIASES = {"µ": "u", "μ": "u", "°": "deg", "·": "*", "Ω": "ohm"}


@functools.lru_cache(maxsize=4096)
def parse_unit(text: str) -> tuple[float, Dims]:
    """Unit string -> (factor to SI, dimension vector). Raises UnitError.

    Looks in the shipped table of common units, then in the per-user cache, and only then asks
    pint (whose import costs ~0.44 s); pint's answers are added to the per-user cache.
    """
    from acl._unit_table import TABLE

    hit = TABLE.get(text)
    if hit is not None:
        return hit
    _refuse_before_pint(text)
    cache = _disk_cache()
    if text in cache:
        f, d = cache[text]
        return float(f), tuple(int(x) for x in d)  # type: ignore[return-value]
    result = parse_unit_with_pint(text)
    cache[text] = (result[0], list(result[1]))
    _cache_changed()
    return result


#: the largest exponent of a base unit acl accepts (`m^3`, `s^-2`; `m^99` names no quantity of this domain)
MAX_EXPONENT = 12

#: the largest exponent of a base dimension (`V^-4` is s^12 in base units)
MAX_DIMENSION = 48

_EXPONENT = re.compile(r"(?:\^|\*\*)\s*\(?\s*([-+]?)\s*([0-9]+(?:\.[0-9]*)?)")


def _refuse_before_pint(text: str) -> None:
    """Spellings pint would misread, refused with a hint: a bare micro sign (pint's `u`, the atomic mass unit:
    `1 µ` was 1.66e-27 kg) and exponents beyond :data:`MAX_EXPONENT` (`m^9223372036854775808` was accepted)."""
    bare = text.strip()
    if bare in ("µ", "μ", "u"):
        raise UnitError(f"`{text}` is a prefix without a unit", "micro what? write `um`, `us`, `uN`, `uL` ...")
    for m in _EXPONENT.finditer(text):
        digits = m.group(2)
        if len(digits) > 6 or float(digits) > MAX_EXPONENT:
            raise UnitError(f"unit `{text}`: the exponent {m.group(1)}{digits[:12]}{'...' if len(digits) > 12 else ''} "
                            f"is beyond {MAX_EXPONENT}", "a unit of this domain has small exponents: `m^3`, `s^-2`")


def _cache_dir() -> str:
    return os.environ.get("ACL_CACHE_DIR") or os.path.join(os.path.expanduser("~"), ".cache", "acl")


#: the cache's name carries the rules it was written under: units.json of earlier versions held pint's answers
#: for offset and logarithmic units (`dB` as 3.78) that this version refuses, and must not be read
CACHE_FILE = "units-v2.json"
MAX_CACHE_BYTES = 4 * 2 ** 20     # a units cache larger than this is not read (it is rebuilt)


def _cache_entry(key, value):
    """(factor, dims) of one cached unit, or None when the entry is not one acl could have written."""
    if not isinstance(key, str) or not isinstance(value, list) or len(value) != 2:
        return None
    factor, dims = value
    if (not isinstance(factor, (int, float)) or isinstance(factor, bool) or not math.isfinite(factor) or factor <= 0
            or not isinstance(dims, list) or len(dims) != 7
            or not all(isinstance(x, int) and not isinstance(x, bool) and abs(x) <= MAX_DIMENSION for x in dims)):
        return None
    return float(factor), [int(x) for x in dims]


@functools.lru_cache(maxsize=1)
def _disk_cache() -> dict:
    """The per-user cache of pint's answers.  Anything unreadable or malformed in it is ignored (a corrupt
    cache broke every later run until deleted); only well-formed entries are used."""
    import json

    path = os.path.join(_cache_dir(), CACHE_FILE)
    try:
        if not os.path.isfile(path) or os.path.getsize(path) > MAX_CACHE_BYTES:
            return {}
        with open(path, encoding="utf-8") as fh:
            data = json.load(fh)
    except Exception:            # OSError, ValueError, RecursionError, a 5,000-digit integer...
        return {}
    if not isinstance(data, dict):
        return {}
    out = {}
    for k, v in data.items():
        entry = _cache_entry(k, v)
        if entry is not None:
            out[k] = entry
    return out


_CACHE_DIRTY = False


def _cache_changed() -> None:
    """Save the cache once, when the process ends: every new unit spelling rewrote the whole file (3,000
    params with distinct units took 84-120 s)."""
    global _CACHE_DIRTY
    if not _CACHE_DIRTY:
        import atexit

        _CACHE_DIRTY = True
        atexit.register(flush_unit_cache)


def flush_unit_cache() -> None:
    """Write the units learnt in this process to the per-user cache (atomically; errors ignored)."""
    global _CACHE_DIRTY
    if _CACHE_DIRTY:
        _CACHE_DIRTY = False
        _save_disk_cache(_disk_cache())


def _save_disk_cache(cache: dict) -> None:
    import json
    import tempfile

    tmp = None
    try:
        d = _cache_dir()
        os.makedirs(d, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=d, prefix=".units-", suffix=".json")
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            json.dump(cache, fh)
        os.replace(tmp, os.path.join(d, CACHE_FILE))
    except Exception:
        if tmp and os.path.exists(tmp):
            try:
                os.unlink(tmp)
            except OSError:
                pass           # the cache is an optimisation only


def parse_unit_with_pint(text: str) -> tuple[float, Dims]:
    """The authoritative conversion: pint."""
    norm = text
    for a, b in _ALIASES.items():
        norm = norm.replace(a, b)
    norm = norm.replace("^", "**")
    if norm.strip() == "%":
        return 0.01, DIMENSIONLESS
    try:
        reg = registry()
        q = reg.Quantity(1.0, norm)
        base = q.to_base_units()
        twice = reg.Quantity(2.0, norm).to_base_units().magnitude
        zero = reg.Quantity(0.0, norm).to_base_units().magnitude
    except Exception as exc:
        word = str(exc).split("'")[1] if "'" in str(exc) else text
        raise UnitError(f"unknown unit `{text}`", _unit_hint(word)) from None
    one = float(base.magnitude)
    if not (math.isfinite(one) and one > 0):
        raise UnitError(f"unit `{text}` is not a finite positive multiple of SI units")
    if zero != 0.0 or not math.isclose(float(twice), 2.0 * one, rel_tol=1e-9):
        # degC, degF (offset: `20 degC` was 5483 K), dB, Np, octave (logarithmic: `3 dB` was 3.78)
        raise UnitError(f"unit `{text}` is not a multiple of an SI unit (an offset or a logarithmic scale)",
                        "write temperatures in K (20 degC = 293.15 K) and ratios as plain numbers "
                        "(3 dB of power = 1.995)")
    dims = base.dimensionality
    vec = []
    for b in _BASE:
        e = dims.get(b, 0)
        if e != int(e):
            raise UnitError(f"unit `{text}` has a fractional dimension")
        if abs(e) > MAX_DIMENSION:
            raise UnitError(f"unit `{text}`: the dimension {b}^{e:g} is beyond the exponent {MAX_DIMENSION}")
        vec.append(int(e))
    mag = float(base.magnitude)
    # pint's base unit for mass is kg, for angle radian (dimensionless): both as wanted.
    return mag, tuple(vec)  # type: ignore[return-value]


def _unit_hint(word: str) -> str | None:
    common = {"micron": "um", "microns": "um", "khz": "kHz", "mhz": "MHz (or mHz?)", "v": "V", "nn": "nN",
              "mpa": "MPa (or mPa?)", "degree": "deg", "degrees": "deg", "sec": "s"}
    if word.lower() in common:
        return f"did you mean `{common[word.lower()]}`?"
    return "units are written without spaces (`nN/um`, `kg/m^3`); multiply by a parameter with spaces: `40 um * gap`"


@functools.lru_cache(maxsize=4096)
def _dims_product(a: Dims, b: Dims) -> Dims:
    """Dimension vector of a product (memoised: a design multiplies the same few dimensions thousands of times)."""
    return tuple(x + y for x, y in zip(a, b))  # type: ignore[return-value]


@functools.lru_cache(maxsize=4096)
def _dims_quotient(a: Dims, b: Dims) -> Dims:
    """Dimension vector of a quotient (memoised as the product)."""
    return tuple(x - y for x, y in zip(a, b))  # type: ignore[return-value]


@dataclass(frozen=True, slots=True)
class Quantity:
    """An SI value with a dimension vector."""

    value: float
    dims: Dims = DIMENSIONLESS

    @property
    def dimensionless(self) -> bool:
        return self.dims == DIMENSIONLESS

    def __add__(self, other: "Quantity") -> "Quantity":
        if self.dims != other.dims:
            raise DimensionError(self.dims, other.dims, "+")
        return Quantity(self.value + other.value, self.dims)

    def __sub__(self, other: "Quantity") -> "Quantity":
        if self.dims != other.dims:
            raise DimensionError(self.dims, other.dims, "-")
        return Quantity(self.value - other.value, self.dims)

    def __mul__(self, other: "Quantity") -> "Quantity":
        return Quantity(self.value * other.value, _dims_product(self.dims, other.dims))

    def __truediv__(self, other: "Quantity") -> "Quantity":
        if other.value == 0:
            raise ZeroDivisionError("division by zero")
        return Quantity(self.value / other.value, _dims_quotient(self.dims, other.dims))

    def __neg__(self) -> "Quantity":
        return Quantity(-self.value, self.dims)

    def __pow__(self, other: "Quantity") -> "Quantity":
        if not other.dimensionless:
            raise DimensionError(other.dims, DIMENSIONLESS, "^")
        e = other.value
        if not self.dimensionless and e != int(e):
            raise ValueError("a quantity with units can only be raised to an integer power")
        v = self.value ** e
        if isinstance(v, complex) or (isinstance(v, float) and math.isnan(v)):
            raise ValueError("power of a negative number is not real")
        return Quantity(float(v), tuple(int(d * e) for d in self.dims))  # type: ignore[arg-type]

    def __str__(self) -> str:
        return format_quantity(self.value, self.dims)


class DimensionError(ValueError):
    def __init__(self, a: Dims, b: Dims, op: str):
        super().__init__(f"cannot combine {describe(a)} and {describe(b)} with `{op}`")
        self.a, self.b, self.op = a, b, op


def quantity(value: float, unit: str) -> Quantity:
    factor, dims = parse_unit(unit)
    return Quantity(value * factor, dims)


def dims_of(unit: str) -> Dims:
    return parse_unit(unit)[1]


# Named dimensions for messages and for SI unit strings.
_NAMED: dict[Dims, tuple[str, str]] = {}


def _register(name: str, unit: str, si: str) -> None:
    _NAMED[parse_unit_static(unit)] = (name, si)


@functools.lru_cache(maxsize=None)
def parse_unit_static(unit: str) -> Dims:
    """Dimension vectors of common units without touching pint (keeps start-up low)."""
    table = {
        "m": (1, 0, 0, 0, 0, 0, 0), "kg": (0, 1, 0, 0, 0, 0, 0), "s": (0, 0, 1, 0, 0, 0, 0),
        "Hz": (0, 0, -1, 0, 0, 0, 0), "V": (2, 1, -3, -1, 0, 0, 0), "Pa": (-1, 1, -2, 0, 0, 0, 0),
        "N": (1, 1, -2, 0, 0, 0, 0), "N/m": (0, 1, -2, 0, 0, 0, 0), "kg/m^3": (-3, 1, 0, 0, 0, 0, 0),
        "Pa*s": (-1, 1, -1, 0, 0, 0, 0), "m/s": (1, 0, -1, 0, 0, 0, 0), "m^2": (2, 0, 0, 0, 0, 0, 0),
        "m^3": (3, 0, 0, 0, 0, 0, 0), "Pa/V": (-3, 0, 1, 1, 0, 0, 0), "N/V^2": (-3, -1, 4, 2, 0, 0, 0),
        "N*m^2/V^2": (-1, -1, 4, 2, 0, 0, 0), "V/s": (2, 1, -4, -1, 0, 0, 0), "m^2/s": (2, 0, -1, 0, 0, 0, 0),
        "": DIMENSIONLESS, "J": (2, 1, -2, 0, 0, 0, 0), "K": (0, 0, 0, 0, 1, 0, 0),
        "N/V": (-1, 0, 1, 1, 0, 0, 0),
    }
    return table[unit]  # type: ignore[return-value]


for _name, _unit in [("length", "m"), ("mass", "kg"), ("time", "s"), ("frequency", "Hz"), ("voltage", "V"),
                     ("pressure", "Pa"), ("force", "N"), ("stiffness or surface tension", "N/m"),
                     ("density", "kg/m^3"), ("dynamic viscosity", "Pa*s"), ("speed", "m/s"), ("area", "m^2"),
                     ("volume", "m^3"), ("pressure per volt", "Pa/V"), ("force per volt squared", "N/V^2"),
                     ("radiation coefficient (force x area per volt squared)", "N*m^2/V^2"),
                     ("slew rate", "V/s"), ("diffusivity", "m^2/s"), ("a dimensionless number", ""),
                     ("energy", "J"), ("temperature", "K"), ("force per volt", "N/V")]:
    _register(_name, _unit, _unit)


def describe(dims: Dims) -> str:
    """Human name of a dimension: 'length', 'frequency', or its SI unit."""
    if dims in _NAMED:
        name, si = _NAMED[dims]
        return f"{name} [{si}]" if si else name
    return f"[{si_unit(dims)}]"


def si_unit(dims: Dims) -> str:
    if dims in _NAMED:
        return _NAMED[dims][1]
    parts = []
    for sym, e in zip(_SYMBOL, dims):
        if e == 1:
            parts.append(sym)
        elif e:
            parts.append(f"{sym}^{e}")
    return "*".join(parts)


def format_quantity(value: float, dims: Dims) -> str:
    unit = si_unit(dims)
    return f"{value:.6g} {unit}".strip()


_PREFIXES = [(1e9, "G"), (1e6, "M"), (1e3, "k"), (1.0, ""), (1e-3, "m"), (1e-6, "u"), (1e-9, "n"), (1e-12, "p")]


def format_si(value: float | None, unit: str) -> str:
    """A value in SI `unit` with an engineering prefix: 1.3e-5 m -> '13 um'. Compound units unprefixed."""
    if value is None:
        return "-"
    if unit in ("", None):
        return f"{value:.4g}"
    if any(ch in unit for ch in "*/^") or value == 0:
        return f"{value:.4g} {unit}"
    mag = abs(value)
    for f, p in _PREFIXES:
        if mag >= f * 0.9995:
            return f"{value / f:.4g} {p}{unit}"
    return f"{value:.4g} {unit}"


def regenerate_table(path: str | None = None) -> int:
    """Rewrite acl/_unit_table.py from pint for the units it lists; returns the number of units."""
    from acl._unit_table import TABLE

    path = path or os.path.join(os.path.dirname(__file__), "_unit_table.py")
    with open(path, encoding="utf-8") as fh:
        head = fh.read().split("TABLE = {")[0]
    lines = [f"    {u!r}: {parse_unit_with_pint(u)!r},\n" for u in TABLE]
    with open(path, "w", encoding="utf-8") as fh:
        fh.write(head + "TABLE = {\n" + "".join(lines) + "}\n")
    return len(lines)


if __name__ == "__main__":  # python -m acl.units --regenerate
    import sys

    if sys.argv[1:] == ["--regenerate"]:
        print(f"{regenerate_table()} units written")
    else:
        print("usage: python -m acl.units --regenerate")


_DECIMAL = re.compile(r"^\s*[-+]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][-+]?[0-9]+)?\s*$")


def parse_decimal(text: str) -> float:
    """A number as a CSV file holds it (ASCII decimal, optional exponent; ``nan``/``inf`` pass for the caller to
    refuse as not finite).  Raises ValueError for what Python's float() reads but a data file does not mean:
    ``1_000``, non-ASCII digits (``١٢``)."""
    if not _DECIMAL.match(text) and text.strip().lower().lstrip("+-") not in ("nan", "inf", "infinity"):
        raise ValueError(f"could not convert string to float: {text!r}")
    return float(text)


# Conventional units a parameter's SI unit string is shown in (`m^-4*kg^-2*s^6*A^2` -> `1/V^2`, `m^2*kg*s^-3` -> `W`);
# lengths are shown in um.  The first whose dimension matches wins.
CONVENTIONAL = ("Pa", "N", "V", "J", "W", "Hz", "N/m", "Pa*s", "N/V^2", "N*m^2/V^2", "Pa/V", "N/V", "1/V^2", "1/V",
                "V^2", "V/s", "m/s", "m^2/s", "kg/m^3", "kg/s", "1/m", "1/s^2", "A", "ohm", "F", "C")


def conventional_unit(unit: str) -> str:
    """The conventional spelling of an SI unit string (itself when none in :data:`CONVENTIONAL` matches)."""
    if not unit or unit in CONVENTIONAL:
        return unit or ""
    try:
        dims = parse_unit(unit)[1]
        return next((u for u in CONVENTIONAL if parse_unit(u)[1] == dims), unit)
    except (UnitError, ValueError):
        return unit


# lengths and speeds of a micro-mechanism print in um (SI inside, units at edges)
_MICRO = {"m": (1e6, "um"), "m/s": (1e6, "um/s")}


def shown_unit(unit: str) -> tuple[float, str]:
    """(scale, unit) a value in SI ``unit`` is printed with: um and um/s for lengths and speeds, else
    :func:`conventional_unit`."""
    return _MICRO.get(unit) or (1.0, conventional_unit(unit))
