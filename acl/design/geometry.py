"""Capsule and cavity geometry: volumes, face placement of orifices, extents (support functions)."""
from __future__ import annotations

import math

Vec = tuple[float, float, float]


def dot(a: Vec, b: Vec) -> float:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def add(a: Vec, b: Vec) -> Vec:
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


def sub(a: Vec, b: Vec) -> Vec:
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def scale(a: Vec, s: float) -> Vec:
    return (a[0] * s, a[1] * s, a[2] * s)


def norm(a: Vec) -> float:
    return math.sqrt(dot(a, a))


def cross(a: Vec, b: Vec) -> Vec:
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def rotate(v: Vec, axis: Vec, angle: float) -> Vec:
    """Rodrigues' rotation of v about unit axis."""
    c, s = math.cos(angle), math.sin(angle)
    k = axis
    kxv = cross(k, v)
    kdv = dot(k, v)
    return tuple(v[i] * c + kxv[i] * s + k[i] * kdv * (1 - c) for i in range(3))  # type: ignore[return-value]


def perpendicular(axis: Vec) -> Vec:
    """A unit vector perpendicular to axis: +x projected, else +y."""
    for cand in ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0)):
        p = sub(cand, scale(axis, dot(cand, axis)))
        n = norm(p)
        if n > 1e-6:
            return scale(p, 1 / n)
    return (0.0, 0.0, 1.0)


def cylinder_volume(radius: float, height: float) -> float:
    return math.pi * radius**2 * height


def prism_volume(side: float, height: float) -> float:
    return math.sqrt(3) / 4 * side**2 * height


def prism_inradius(side: float) -> float:
    return side / (2 * math.sqrt(3))


def half_extent(shape: str, u: Vec, axis: Vec, radius=None, side=None, height=None, volume=None, wall=0.0) -> float:
    """Support function of the capsule's outer body along unit direction u (from its centre)."""
    if shape == "cylinder":
        ca = abs(dot(u, axis))
        return ca * height / 2 + radius * math.sqrt(max(0.0, 1 - ca * ca)) + wall
    if shape == "prism":
        ca = abs(dot(u, axis))
        circum = side / math.sqrt(3)
        return ca * height / 2 + circum * math.sqrt(max(0.0, 1 - ca * ca)) + wall
    return (3 * volume / (4 * math.pi)) ** (1 / 3) + wall


def inscribed_radius(shape: str, radius=None, side=None, height=None, volume=None) -> float:
    if shape == "cylinder":
        return min(radius, height / 2)
    if shape == "prism":
        return min(prism_inradius(side), height / 2)
    return (3 * volume / (4 * math.pi)) ** (1 / 3) * 0.5


def bounding_radius(shape: str, radius=None, side=None, height=None, volume=None, wall=0.0) -> float:
    """Radius of the smallest centred sphere containing the capsule's outer body."""
    if shape == "cylinder":
        return math.hypot(radius, height / 2) + wall
    if shape == "prism":
        return math.hypot(side / math.sqrt(3), height / 2) + wall
    return (3 * volume / (4 * math.pi)) ** (1 / 3) + wall
