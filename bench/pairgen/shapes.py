"""Triangle meshes of tabletop objects, built here from their dimensions (no mesh files, nothing shared with the
project's simulator): boxes, cylinders, bottles, mugs with a handle, bowls, pans with a handle, plates, balls.

Object frame: z up, the object's lowest point on z = 0 when upright, the axis of a body of revolution on z. Every
triangle carries its three vertex normals so the renderer can shade curved surfaces smoothly and box faces flat.
Each shape also says which rotations its geometry alone cannot show (the candidates a texture may still break).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

KINDS = ("box", "cylinder", "bottle", "mug", "bowl", "pan", "plate", "ball")
SEGMENTS = 48  # around a body of revolution


@dataclass(frozen=True)
class Mesh:
    """Triangles (T, 3, 3) [m] with their vertex normals (T, 3, 3), object frame."""

    triangles: np.ndarray
    normals: np.ndarray

    def transformed(self, T: np.ndarray) -> Mesh:
        R, t = T[:3, :3], T[:3, 3]
        return Mesh(self.triangles @ R.T + t, self.normals @ R.T)

    def __add__(self, other: Mesh) -> Mesh:
        return Mesh(np.concatenate([self.triangles, other.triangles]), np.concatenate([self.normals, other.normals]))

    @property
    def vertices(self) -> np.ndarray:
        return self.triangles.reshape(-1, 3)

    def sample_surface(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """(n, 3) points spread over the surface by area."""
        a, b, c = self.triangles[:, 0], self.triangles[:, 1], self.triangles[:, 2]
        area = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
        k = rng.choice(len(area), n, p=area / area.sum())
        r1, r2 = rng.random(n), rng.random(n)
        flip = r1 + r2 > 1
        r1, r2 = np.where(flip, 1 - r1, r1), np.where(flip, 1 - r2, r2)
        return a[k] + r1[:, None] * (b[k] - a[k]) + r2[:, None] * (c[k] - a[k])


@dataclass(frozen=True)
class ShapeSymmetry:
    """What the geometry alone cannot show: discrete rotations about the shape's centre (object frame, each
    (3, 3)), and for a body of revolution every turn about z (with `flip`: also end-for-end turns), or every
    rotation (ball)."""

    rotations: np.ndarray  # (K, 3, 3), identity first
    revolution: bool = False
    flip: bool = False
    ball: bool = False


@dataclass(frozen=True)
class Shape:
    kind: str
    mesh: Mesh
    symmetry: ShapeSymmetry
    dims_m: dict[str, float]

    @property
    def centre(self) -> np.ndarray:
        """Centre of the bounding box (object frame): where positions are scored."""
        v = self.mesh.vertices
        return 0.5 * (v.min(axis=0) + v.max(axis=0))

    @property
    def size_m(self) -> float:
        v = self.mesh.vertices
        return float(np.linalg.norm(np.ptp(v, axis=0)))


def _quad(a, b, c, d, n) -> tuple[np.ndarray, np.ndarray]:
    tri = np.array([[a, b, c], [a, c, d]], dtype=np.float64)
    return tri, np.broadcast_to(np.asarray(n, dtype=np.float64), (2, 3, 3)).copy()


def box_mesh(size: tuple[float, float, float], centre=(0.0, 0.0, 0.0)) -> Mesh:
    """An axis-aligned box with flat faces."""
    h = np.asarray(size, dtype=np.float64) / 2
    c = np.asarray(centre, dtype=np.float64)
    tris, norms = [], []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            n = np.zeros(3)
            n[axis] = sign
            u, v = np.eye(3)[(axis + 1) % 3], np.eye(3)[(axis + 2) % 3]
            f = c + n * h[axis]
            du, dv = u * h[(axis + 1) % 3], v * h[(axis + 2) % 3]
            t, nn = _quad(f - du - dv, f + du - dv, f + du + dv, f - du + dv, n)
            tris.append(t)
            norms.append(nn)
    return Mesh(np.concatenate(tris), np.concatenate(norms))


def lathe(profile: list[tuple[float, float]], segments: int = SEGMENTS) -> Mesh:
    """Revolve a polyline of (radius, z) points about z. Each band between two profile points gets the normal of
    its segment (smooth around the axis, creased along the profile); the renderer faces normals to the camera, so
    the profile's direction does not matter."""
    p = np.asarray(profile, dtype=np.float64)
    ang = np.linspace(0.0, 2 * math.pi, segments + 1)
    cos, sin = np.cos(ang), np.sin(ang)
    tris, norms = [], []
    for (r0, z0), (r1, z1) in itertools.pairwise(p):
        dr, dz = r1 - r0, z1 - z0
        length = math.hypot(dr, dz)
        if length < 1e-9:
            continue
        nr, nz = dz / length, -dr / length  # perpendicular to the segment in the (r, z) plane
        a0 = np.stack([r0 * cos, r0 * sin, np.full_like(cos, z0)], axis=1)
        a1 = np.stack([r1 * cos, r1 * sin, np.full_like(cos, z1)], axis=1)
        n = np.stack([nr * cos, nr * sin, np.full_like(cos, nz)], axis=1)
        for k in range(segments):
            tris += [[a0[k], a0[k + 1], a1[k + 1]], [a0[k], a1[k + 1], a1[k]]]
            norms += [[n[k], n[k + 1], n[k + 1]], [n[k], n[k + 1], n[k]]]
    return Mesh(np.asarray(tris), np.asarray(norms))


def tube(path: np.ndarray, radius: float, sides: int = 12) -> Mesh:
    """A tube of circular section swept along a polyline (N, 3): a handle."""
    path = np.asarray(path, dtype=np.float64)
    tangent = np.gradient(path, axis=0)
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    ref = np.array([0.0, 1.0, 0.0]) if abs(tangent[0] @ [0, 1, 0]) < 0.9 else np.array([1.0, 0.0, 0.0])
    ang = np.linspace(0.0, 2 * math.pi, sides + 1)
    rings, ring_n = [], []
    for p, t in zip(path, tangent, strict=True):
        a = np.cross(t, ref)
        a /= np.linalg.norm(a)
        b = np.cross(t, a)
        n = np.cos(ang)[:, None] * a + np.sin(ang)[:, None] * b
        rings.append(p + radius * n)
        ring_n.append(n)
    tris, norms = [], []
    for i in range(len(path) - 1):
        r0, r1, n0, n1 = rings[i], rings[i + 1], ring_n[i], ring_n[i + 1]
        for k in range(sides):
            tris += [[r0[k], r0[k + 1], r1[k + 1]], [r0[k], r1[k + 1], r1[k]]]
            norms += [[n0[k], n0[k + 1], n1[k + 1]], [n0[k], n1[k + 1], n1[k]]]
    return Mesh(np.asarray(tris), np.asarray(norms))


def _cube_rotations() -> np.ndarray:
    """(24, 3, 3) the proper rotations mapping coordinate axes onto coordinate axes, identity first."""
    out = []
    for perm in ((0, 1, 2), (1, 2, 0), (2, 0, 1), (0, 2, 1), (2, 1, 0), (1, 0, 2)):
        for signs in np.ndindex(2, 2, 2):
            P = np.zeros((3, 3))
            P[np.arange(3), perm] = np.where(np.array(signs) == 1, -1.0, 1.0)
            if np.linalg.det(P) > 0:
                out.append(P)
    out.sort(key=lambda P: -np.trace(P))
    return np.array(out)


CUBE_ROTATIONS = _cube_rotations()


def box_symmetry(size: tuple[float, float, float], tol_m: float = 1e-4) -> ShapeSymmetry:
    """The cube rotations that map a box of these edge lengths onto itself (4, 8 or 24)."""
    s = np.asarray(size)
    keep = [P for P in CUBE_ROTATIONS if np.all(np.abs(np.abs(P) @ s - s) < tol_m)]
    return ShapeSymmetry(np.array(keep))


NO_SYMMETRY = ShapeSymmetry(np.eye(3)[None])


def _revolution(flip: bool) -> ShapeSymmetry:
    return ShapeSymmetry(np.eye(3)[None], revolution=True, flip=flip)


def make_shape(kind: str, rng: np.random.Generator) -> Shape:
    """A random instance of `kind` with plausible tabletop dimensions."""
    u = rng.uniform
    if kind == "box":
        r = rng.random()
        if r < 0.25:
            a = u(0.025, 0.08)
            size = (a, a, a)
        elif r < 0.45:
            a, c = u(0.03, 0.09), u(0.03, 0.14)
            size = (a, a, c)
        else:
            size = (u(0.025, 0.14), u(0.025, 0.12), u(0.025, 0.12))
        centre = np.array([0.0, 0.0, size[2] / 2])
        mesh = box_mesh(size, centre)
        return Shape(kind, mesh, box_symmetry(size), {"x": size[0], "y": size[1], "z": size[2]})
    if kind == "cylinder":
        r, h = u(0.02, 0.05), u(0.03, 0.15)
        mesh = lathe([(0, 0), (r, 0), (r, h), (0, h)])
        return Shape(kind, mesh, _revolution(True), {"radius": r, "height": h})
    if kind == "bottle":
        r, h = u(0.025, 0.045), u(0.14, 0.26)
        neck, body = u(0.3, 0.45) * r, u(0.55, 0.7) * h
        shoulder = body + u(0.1, 0.16) * h
        mesh = lathe(
            [(0, 0), (r * 0.92, 0), (r, 0.01), (r, body), (neck, shoulder), (neck, h - 0.012), (neck * 1.15, h - 0.012),
             (neck * 1.15, h), (0, h)]
        )  # fmt: skip
        return Shape(kind, mesh, _revolution(False), {"radius": r, "height": h})
    if kind == "mug":
        r, h, wall = u(0.035, 0.05), u(0.08, 0.11), 0.004
        body = lathe([(0, 0), (r, 0), (r, h), (r - wall, h), (r - wall, 0.006), (0, 0.006)])
        hr, tube_r = u(0.25, 0.35) * h, u(0.005, 0.007)
        ang = np.linspace(-math.pi / 2, math.pi / 2, 14)
        zc = h / 2
        path = np.stack([r - 0.004 + hr * 0.9 * np.cos(ang), np.zeros_like(ang), zc + hr * np.sin(ang)], axis=1)
        mesh = body + tube(path, tube_r)
        return Shape(kind, mesh, NO_SYMMETRY, {"radius": r, "height": h})
    if kind == "bowl":
        r, h = u(0.06, 0.10), u(0.04, 0.07)
        foot, wall = u(0.4, 0.55) * r, 0.005
        k = np.linspace(0, 1, 8)
        outer = [(foot + (r - foot) * math.sin(a * math.pi / 2), h * (1 - math.cos(a * math.pi / 2))) for a in k]
        inner = [(max(0.0, rr - wall), max(zz, 0.0) + wall) for rr, zz in outer[::-1]]
        mesh = lathe([(0, 0), *outer, (r - wall / 2, h + 0.002), *inner, (0, wall)])
        return Shape(kind, mesh, _revolution(False), {"radius": r, "height": h})
    if kind == "pan":
        r, h, wall = u(0.08, 0.12), u(0.03, 0.05), 0.004
        body = lathe([(0, 0), (r, 0), (r, h), (r - wall, h), (r - wall, wall), (0, wall)])
        length, width = u(0.10, 0.16), u(0.022, 0.03)
        handle = box_mesh((length, width, 0.012), (r + length / 2 - 0.005, 0.0, h - 0.008))
        return Shape(kind, body + handle, NO_SYMMETRY, {"radius": r, "height": h})
    if kind == "plate":
        r, h = u(0.08, 0.13), u(0.015, 0.025)
        well = u(0.6, 0.75) * r
        mesh = lathe([(0, 0), (well, 0), (r, h), (r - 0.004, h + 0.001), (well, 0.004), (0, 0.004)])
        return Shape(kind, mesh, _revolution(False), {"radius": r, "height": h})
    if kind == "ball":
        r = u(0.025, 0.05)
        a = np.linspace(-math.pi / 2, math.pi / 2, 20)
        mesh = lathe([(r * math.cos(t), r + r * math.sin(t)) for t in a], segments=40)
        sym = ShapeSymmetry(np.eye(3)[None], ball=True)
        return Shape(kind, mesh, sym, {"radius": r})
    raise ValueError(f"unknown shape kind {kind!r} (known: {', '.join(KINDS)})")
