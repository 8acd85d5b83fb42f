"""A ray caster for tabletop scenes on Open3D's RaycastingScene: one ray per pixel for colour, depth and which
object is seen, a shadow ray per hit towards a directional light, Lambert and Blinn-Phong shading with smooth
vertex normals. It shares nothing with the project's MuJoCo renderer.

World frame: z up, the table top at z = 0. Camera frame: x right, y down, z forward (the project's optical frame);
pixels have integer coordinates at their centres, so depth is the z of the hit in the camera frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bench.pairgen.materials import Material
from bench.pairgen.shapes import Mesh, Shape
from drivers.types import CameraIntrinsics

TABLE_HALF_M = 6.0
NO_HIT = -1
TABLE_ID = 0


@dataclass(frozen=True)
class Light:
    direction: np.ndarray  # unit, from the scene towards the light, world frame
    intensity: float
    ambient: float
    tint: np.ndarray  # (3,) colour of the light


@dataclass(frozen=True)
class Placed:
    """An object in the scene: its shape and material, posed by T_world_object."""

    shape: Shape
    material: Material
    T_world_object: np.ndarray


@dataclass(frozen=True)
class Render:
    rgb: np.ndarray  # (H, W, 3) float 0..1, before any sensor effect
    depth: np.ndarray  # (H, W) z in the camera frame [m], inf where no ray hit
    ids: np.ndarray  # (H, W) int: NO_HIT, TABLE_ID, or 1 + the index of the object seen


def table_mesh() -> Mesh:
    h = TABLE_HALF_M
    tri = np.array([[[-h, -h, 0], [h, -h, 0], [h, h, 0]], [[-h, -h, 0], [h, h, 0], [-h, h, 0]]], dtype=np.float64)
    return Mesh(tri, np.broadcast_to(np.array([0.0, 0.0, 1.0]), (2, 3, 3)).copy())


def camera_rays(K: CameraIntrinsics, T_world_camera: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(origin (3,), directions (H, W, 3)) of the pixel rays, scaled so the ray parameter is camera-frame z."""
    u, v = np.meshgrid(np.arange(K.width, dtype=np.float64), np.arange(K.height, dtype=np.float64))
    d_cam = np.stack([(u - K.cx) / K.fx, (v - K.cy) / K.fy, np.ones_like(u)], axis=-1)
    return T_world_camera[:3, 3].copy(), d_cam @ T_world_camera[:3, :3].T


def _scene(meshes: list[Mesh]):
    import open3d as o3d

    scene = o3d.t.geometry.RaycastingScene()
    for m in meshes:
        verts = m.triangles.reshape(-1, 3).astype(np.float32)
        tris = np.arange(len(verts), dtype=np.uint32).reshape(-1, 3)
        scene.add_triangles(o3d.core.Tensor(verts), o3d.core.Tensor(tris))
    return scene


def _cast(scene, K: CameraIntrinsics, T_world_camera: np.ndarray) -> tuple[np.ndarray, np.ndarray, dict]:
    import open3d as o3d

    origin, dirs = camera_rays(K, T_world_camera)
    rays = np.concatenate([np.broadcast_to(origin, dirs.shape), dirs], axis=-1).reshape(-1, 6).astype(np.float32)
    return origin, dirs, scene.cast_rays(o3d.core.Tensor(rays))


def silhouette(K: CameraIntrinsics, T_world_camera: np.ndarray, placed: Placed) -> np.ndarray:
    """(H, W) bool: the pixels the object alone would cover (no table, no other object)."""
    _, _, hit = _cast(_scene([placed.shape.mesh.transformed(placed.T_world_object)]), K, T_world_camera)
    return np.isfinite(hit["t_hit"].numpy()).reshape(K.height, K.width)


def render(K: CameraIntrinsics, T_world_camera: np.ndarray, objects: list[Placed], table: Material, light: Light):
    """Render the table and `objects` seen from the camera; returns a Render."""
    import open3d as o3d

    meshes = [table_mesh()] + [o.shape.mesh.transformed(o.T_world_object) for o in objects]
    scene = _scene(meshes)
    origin, dirs, hit = _cast(scene, K, T_world_camera)
    H, W = K.height, K.width
    t = hit["t_hit"].numpy().astype(np.float64)
    gid = hit["geometry_ids"].numpy().astype(np.int64)
    pid = hit["primitive_ids"].numpy().astype(np.int64)
    uv = hit["primitive_uvs"].numpy().astype(np.float64)
    found = np.isfinite(t)
    ids = np.where(found, gid, NO_HIT)
    d = dirs.reshape(-1, 3)
    p = origin + t[:, None] * d
    normals = np.zeros_like(p)
    colour = np.zeros_like(p)
    spec = np.zeros(len(p))
    shininess = np.ones(len(p))
    materials = [table] + [o.material for o in objects]
    poses = [np.eye(4)] + [o.T_world_object for o in objects]
    for g, (m, mat, T) in enumerate(zip(meshes, materials, poses, strict=True)):
        sel = np.flatnonzero(found & (gid == g))
        if len(sel) == 0:
            continue
        w = np.stack([1 - uv[sel, 0] - uv[sel, 1], uv[sel, 0], uv[sel, 1]], axis=1)
        n = np.einsum("kj,kji->ki", w, m.normals[pid[sel]])
        normals[sel] = n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
        p_obj = (p[sel] - T[:3, 3]) @ T[:3, :3]
        colour[sel] = mat.colour(p_obj)
        spec[sel], shininess[sel] = mat.specular, mat.shininess
    d_unit = d / np.linalg.norm(d, axis=1, keepdims=True)
    facing = np.einsum("ij,ij->i", normals, d_unit) > 0
    normals[facing] *= -1.0  # shade the side the camera sees (insides of mugs and bowls)
    lit = np.zeros(len(p), dtype=bool)
    idx = np.flatnonzero(found)
    if len(idx):
        starts = p[idx] + 1e-3 * normals[idx]
        shadow_rays = np.concatenate([starts, np.broadcast_to(light.direction, starts.shape)], axis=1)
        occluded = scene.test_occlusions(o3d.core.Tensor(shadow_rays.astype(np.float32))).numpy()
        lit[idx] = ~occluded
    lambert = np.clip(normals @ light.direction, 0.0, None) * lit
    half = light.direction - d_unit
    half /= np.linalg.norm(half, axis=1, keepdims=True)
    highlight = spec * np.clip(np.einsum("ij,ij->i", normals, half), 0.0, None) ** shininess * lit
    rgb = (
        colour * (light.ambient + light.intensity * lambert)[:, None] * light.tint
        + (light.intensity * highlight)[:, None] * light.tint
    )
    rgb[~found] = 0.0
    depth = np.where(found, t, np.inf)
    return Render(np.clip(rgb, 0, 1).reshape(H, W, 3), depth.reshape(H, W), ids.reshape(H, W))


def visible(T_world_camera: np.ndarray, objects: list[Placed], points_world: np.ndarray, tol_m: float = 0.002):
    """(N,) bool: which points the camera sees (the first surface along the ray to each is the point itself)."""
    import open3d as o3d

    scene = _scene([table_mesh()] + [o.shape.mesh.transformed(o.T_world_object) for o in objects])
    origin = T_world_camera[:3, 3]
    d = points_world - origin
    dist = np.linalg.norm(d, axis=1)
    rays = np.concatenate([np.broadcast_to(origin, d.shape), d / dist[:, None]], axis=1).astype(np.float32)
    t = scene.cast_rays(o3d.core.Tensor(rays))["t_hit"].numpy()
    return t >= dist - tol_m
