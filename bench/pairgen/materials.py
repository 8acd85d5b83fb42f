"""Procedural surface colour as a function of the object-frame point: uniform colours, stripes, checkers, blobs,
speckle, decals and wrapped labels; and the partial re-texturing an image editor does when it re-draws an object.

A colour that depends only on the object-frame point moves with the object, so the true symmetry of a textured
object can be tested exactly: a rotation is a symmetry when it maps every surface point to one of the same
colour.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

PATTERNS = ("uniform", "stripes", "checker", "blobs", "speckle")


def hsv_to_rgb(h: float, s: float, v: float) -> np.ndarray:
    """One colour, hue in turns (0..1)."""
    i = int(h * 6) % 6
    f = h * 6 - math.floor(h * 6)
    p, q, t = v * (1 - s), v * (1 - f * s), v * (1 - (1 - f) * s)
    return np.array([(v, t, p), (q, v, p), (p, v, t), (p, q, v), (t, p, v), (v, p, q)][i])


def random_colour(rng: np.random.Generator, avoid_hue: float | None = None) -> np.ndarray:
    """A colour of any hue, saturation and brightness a tabletop object may have (greys included)."""
    h = rng.random()
    if avoid_hue is not None:
        h = (avoid_hue + rng.uniform(0.15, 0.85)) % 1.0
    s = rng.uniform(0.0, 0.2) if rng.random() < 0.2 else rng.uniform(0.35, 0.95)
    return hsv_to_rgb(h, s, rng.uniform(0.25, 0.95))


@dataclass(frozen=True)
class Decal:
    """A patch of another colour: the surface points within `radius` of `centre` (a sticker, a logo)."""

    centre: np.ndarray
    radius: float
    colour: np.ndarray


@dataclass(frozen=True)
class Material:
    """Colour as a function of object-frame points, plus how glossy the surface is."""

    pattern: str
    colours: tuple[np.ndarray, ...]
    period_m: float = 0.02
    direction: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))
    phase: float = 0.0
    waves: np.ndarray = field(default_factory=lambda: np.zeros((0, 4)))  # blobs: (k, [wave vector, phase])
    decals: tuple[Decal, ...] = ()
    label: tuple[float, float, np.ndarray] | None = None  # a band z0..z1 wrapped round the object, its colour
    specular: float = 0.0
    shininess: float = 20.0
    # the editor's partial re-texturing: on the side n.p > d of the plane (n, d) the hue is turned
    retexture: tuple[np.ndarray, float, float] | None = None

    @property
    def uniform(self) -> bool:
        return self.pattern == "uniform" and not self.decals and self.label is None

    def colour(self, p: np.ndarray) -> np.ndarray:
        """(N, 3) colours in 0..1 of object-frame points (N, 3)."""
        p = np.asarray(p, dtype=np.float64)
        a, b = self.colours[0], self.colours[1 % len(self.colours)]
        if self.pattern == "stripes":
            s = np.floor((p @ self.direction) / self.period_m + self.phase) % 2
            out = np.where(s[:, None] > 0, b, a)
        elif self.pattern == "checker":
            cell = np.floor(p / self.period_m + self.phase).sum(axis=1) % 2
            out = np.where(cell[:, None] > 0, b, a)
        elif self.pattern == "blobs":
            f = sum(np.sin(p @ w[:3] + w[3]) for w in self.waves)
            out = np.where((f > 0)[:, None], b, a)
        elif self.pattern == "speckle":
            f = sum(np.sin(p @ w[:3] + w[3]) for w in self.waves) / max(len(self.waves), 1)
            out = a * (1.0 + 0.25 * f)[:, None]
        else:
            out = np.broadcast_to(a, p.shape).copy()
        if self.label is not None:
            z0, z1, c = self.label
            out = np.where(((p[:, 2] >= z0) & (p[:, 2] <= z1))[:, None], c, out)
        for d in self.decals:
            out = np.where((np.linalg.norm(p - d.centre, axis=1) < d.radius)[:, None], d.colour, out)
        if self.retexture is not None:
            n, dist, turn = self.retexture
            side = (p @ n) > dist
            out = np.where(side[:, None], _turn_hue(out, turn), out)
        return np.clip(out, 0.0, 1.0)


def _turn_hue(rgb: np.ndarray, turn: float) -> np.ndarray:
    """Rotate colours about the grey axis by `turn` (turns): a hue change that keeps brightness."""
    axis = np.ones(3) / math.sqrt(3)
    a = 2 * math.pi * turn
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    R = np.eye(3) + math.sin(a) * K + (1 - math.cos(a)) * K @ K
    return rgb @ R.T


def random_material(rng: np.random.Generator, surface: np.ndarray, size_m: float) -> Material:
    """A random object material; `surface` (N, 3) are object-frame surface points (decals are put on them)."""
    a = random_colour(rng)
    b = random_colour(rng, avoid_hue=None)
    r = rng.random()
    pattern = "uniform" if r < 0.4 else str(rng.choice(PATTERNS[1:]))
    direction = np.eye(3)[rng.integers(3)] if rng.random() < 0.7 else _unit(rng.normal(size=3))
    waves = np.array(
        [[*(_unit(rng.normal(size=3)) * 2 * math.pi / rng.uniform(0.02, 0.06)), rng.uniform(0, 2 * math.pi)]
         for _ in range(3)]
    )  # fmt: skip
    decals: tuple[Decal, ...] = ()
    label = None
    if rng.random() < 0.3:  # stickers and logos, on plain objects too
        decals = tuple(
            Decal(surface[rng.integers(len(surface))], rng.uniform(0.15, 0.3) * size_m, random_colour(rng))
            for _ in range(rng.integers(1, 3))
        )
    elif rng.random() < 0.15:
        z = surface[:, 2]
        z0 = rng.uniform(z.min(), z.max())
        label = (z0, z0 + rng.uniform(0.15, 0.4) * (z.max() - z.min()), random_colour(rng))
    glossy = rng.random() < 0.4
    return Material(
        pattern,
        (a, b),
        period_m=rng.uniform(0.008, 0.03),
        direction=direction,
        phase=rng.random(),
        waves=waves,
        decals=decals,
        label=label,
        specular=rng.uniform(0.1, 0.4) if glossy else 0.0,
        shininess=rng.uniform(10, 60),
    )


def partially_retextured(m: Material, rng: np.random.Generator, centre: np.ndarray) -> Material:
    """The same material with its hue turned on one side of a random plane through the object (an editor that
    re-synthesises part of the object's texture)."""
    n = _unit(rng.normal(size=3))
    return replace(m, retexture=(n, float(n @ centre) + rng.uniform(-0.01, 0.01), rng.uniform(0.04, 0.12)))


def table_material(rng: np.random.Generator) -> Material:
    """A table top: wood-like stripes, a checker of tiles, speckle or blobs, large scale."""
    pattern = str(rng.choice(["stripes", "checker", "speckle", "blobs", "uniform"]))
    a = random_colour(rng)
    b = np.clip(a * rng.uniform(0.6, 0.9) + rng.uniform(-0.05, 0.05, 3), 0, 1)
    waves = np.array(
        [[*(_unit(rng.normal(size=3) * [1, 1, 0]) * 2 * math.pi / rng.uniform(0.03, 0.3)), rng.uniform(0, 7)]
         for _ in range(4)]
    )  # fmt: skip
    return Material(
        pattern,
        (a, b),
        period_m=rng.uniform(0.04, 0.15),
        direction=_unit(np.array([*rng.normal(size=2), 0.0])),
        phase=rng.random(),
        waves=waves,
        specular=rng.uniform(0.0, 0.15),
        shininess=rng.uniform(5, 30),
    )


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)
