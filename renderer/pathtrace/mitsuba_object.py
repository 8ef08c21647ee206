"""The scene's object as in-memory Mitsuba meshes: placed in the world, two-sided, of the scene's material, with its colors.

Color, first match wins: the scene's object color; the mesh's vertex (or face) colors; its
UV texture; DEFAULT_OBJECT_SRGB. Faces get flat normals: the geometry is shaded as it is.

Slivers: Mitsuba interpolates vertex attributes with barycentric coordinates it re-solves
in float32 from the hit point and two edges of the face, which cancels catastrophically when
the angle between those edges is near 0 or 180 degrees (colors far outside the corners'
range, even NaN). Each face is therefore started at its best-conditioned corner, and true
slivers (every corner badly conditioned, so the face is a thin line) get one flat color,
the mean of their corners, from a second mesh. Faces without area are dropped.

Material (renderer.scene.MaterialSpec): Mitsuba's `diffuse` when specular and metallic are 0 (today's object);
otherwise its `principled` BSDF with the same three values (specular 0.5 is a dielectric of index 1.5).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

from renderer.color import srgb_to_linear
from renderer.errors import InputError
from renderer.scene import MaterialSpec, ObjectSpec
from renderer.transform import apply_transform, object_to_world

DEFAULT_OBJECT_SRGB = (0.5, 0.5, 0.5)  # an object with neither a set color nor its own colors
MIN_SPECULAR = 1e-3  # principled's specular 0 is an index of refraction of 1, which also blacks out its metal
MIN_ROUGHNESS = 0.05  # the smoothest drawn: roughness 0 is a near-perfect mirror, not a delta the shader lacks
SLIVER_SIN2 = 1e-4  # squared sine of a corner's angle below which float32 barycentrics are unreliable


def object_shapes(obj: ObjectSpec, mesh: trimesh.Trimesh, where: Path | None = None, key: str = "object") -> dict:
    """Mitsuba meshes for the object `obj` made of `mesh` (object coordinates; `where`: its file, for messages), by
    scene-dictionary key (`key`, and `key`_slivers if needed)."""
    _check_mesh(mesh, where)
    material = obj.material
    if mesh.visual.kind == "face":  # one vertex per face corner keeps each face's own color
        mesh = mesh.copy()
        mesh.unmerge_vertices()
    vertices = apply_transform(object_to_world(obj), np.asarray(mesh.vertices)).astype(np.float32)
    good, slivers = condition_faces(vertices, np.asarray(mesh.faces))
    everything = np.concatenate([good, slivers])
    if len(everything) == 0:
        raise InputError("the mesh has no face with an area to render", where)

    if obj.color is not None:
        return {key: _mesh(key, vertices, everything, _rgb(srgb_to_linear(obj.color)), material)}
    if mesh.visual.kind in ("vertex", "face"):
        colors = srgb_to_linear(np.asarray(mesh.visual.vertex_colors)[:, :3] / 255.0)
        shapes = {}
        if len(good):
            reflectance = {"type": "mesh_attribute", "name": "vertex_color"}
            shapes[key] = _mesh(key, vertices, good, reflectance, material, attribute=("vertex_color", colors))
        if len(slivers):
            reflectance = {"type": "mesh_attribute", "name": "face_color"}
            flat = colors[slivers].mean(axis=1)
            shapes[f"{key}_slivers"] = _mesh(f"{key}_slivers", vertices, slivers, reflectance, material,
                                             attribute=("face_color", flat))
        return shapes
    texture = _texture_image(mesh)
    if texture is not None:
        import mitsuba as mi

        uv = np.asarray(mesh.visual.uv, dtype=np.float64)
        uv = np.stack([uv[:, 0], 1.0 - uv[:, 1]], axis=1)  # trimesh: v up from the bottom; Mitsuba: from the top
        reflectance = {"type": "bitmap", "bitmap": mi.Bitmap(texture), "raw": True, "wrap_mode": "repeat"}
        return {key: _mesh(key, vertices, everything, reflectance, material, uv=uv)}
    return {key: _mesh(key, vertices, everything, _rgb(srgb_to_linear(DEFAULT_OBJECT_SRGB)), material)}


def condition_faces(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Faces cyclically rotated to start at their best-conditioned corner, split into (well conditioned, slivers).

    A corner's condition is the squared sine of its angle; rotating keeps the winding. Faces
    whose float32 edge cross product is exactly zero have no area and are dropped.
    """
    faces = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    p = np.asarray(vertices, dtype=np.float32)[faces]  # (F, 3 corners, 3)
    sin2 = np.stack([_corner_sin2(p, k) for k in range(3)], axis=1)
    has_area = np.any(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]) != 0, axis=1)
    best = np.argmax(sin2, axis=1)
    rotated = np.take_along_axis(faces, (best[:, None] + np.arange(3)[None, :]) % 3, axis=1)
    well = sin2.max(axis=1) >= SLIVER_SIN2
    return rotated[has_area & well], rotated[has_area & ~well]


def _corner_sin2(p: np.ndarray, k: int) -> np.ndarray:
    """Squared sine of the angle at corner k of each triangle, in float64."""
    a = p[:, k].astype(np.float64)
    du = p[:, (k + 1) % 3].astype(np.float64) - a
    dv = p[:, (k + 2) % 3].astype(np.float64) - a
    cross2 = np.sum(np.cross(du, dv) ** 2, axis=1)
    lengths2 = np.sum(du**2, axis=1) * np.sum(dv**2, axis=1)
    return np.divide(cross2, lengths2, out=np.zeros_like(cross2), where=lengths2 > 0)


def _rgb(linear: np.ndarray) -> dict:
    return {"type": "rgb", "value": np.asarray(linear, dtype=np.float64).tolist()}


def material_bsdf(reflectance: dict, material: MaterialSpec) -> dict:
    """The Mitsuba BSDF of `material` with albedo `reflectance` (one-sided): `diffuse` for a diffuse object, else
    Disney's principled BSDF (the only one of Mitsuba's coated models that takes per-vertex colors)."""
    if material.diffuse_only:
        return {"type": "diffuse", "reflectance": reflectance}
    return {"type": "principled", "base_color": reflectance, "roughness": max(material.roughness, MIN_ROUGHNESS),
            "metallic": material.metallic, "specular": max(material.specular, MIN_SPECULAR)}


def _mesh(name: str, vertices: np.ndarray, faces: np.ndarray, reflectance: dict, material: MaterialSpec,
          uv: np.ndarray | None = None, attribute: tuple[str, np.ndarray] | None = None):
    """One Mitsuba mesh with a two-sided BSDF of `material`."""
    return numpy_mesh(name, vertices, faces, {"type": "twosided", "material": material_bsdf(reflectance, material)},
                      uv, attribute)


def numpy_mesh(name: str, vertices: np.ndarray, faces: np.ndarray, bsdf: dict, uv: np.ndarray | None = None,
               attribute: tuple[str, np.ndarray] | None = None):
    """One Mitsuba mesh of `bsdf` (a scene-dictionary entry), its buffers filled from numpy (no files)."""
    import mitsuba as mi

    props = mi.Properties()
    props["bsdf"] = mi.load_dict(bsdf)
    out = mi.Mesh(name, len(vertices), len(faces), props=props, has_vertex_texcoords=uv is not None)
    params = mi.traverse(out)
    floats, ints = type(params["vertex_positions"]), type(params["faces"])  # drjit types differ per variant
    params["vertex_positions"] = floats(np.ascontiguousarray(vertices, dtype=np.float32).ravel())
    params["faces"] = ints(np.ascontiguousarray(faces, dtype=np.uint32).ravel())
    if uv is not None:
        params["vertex_texcoords"] = floats(np.ascontiguousarray(uv, dtype=np.float32).ravel())
    params.update()
    if attribute is not None:
        key, values = attribute
        out.add_attribute(key, 3, floats(np.ascontiguousarray(values, dtype=np.float32).ravel()))
    return out


def _check_mesh(mesh: trimesh.Trimesh, where: Path | None) -> None:
    if len(mesh.faces) == 0 or len(mesh.vertices) == 0:
        raise InputError("the mesh has no faces to render", where)
    if not np.all(np.isfinite(mesh.vertices)):
        raise InputError("the mesh has NaN or infinite vertex coordinates", where)


def _texture_image(mesh: trimesh.Trimesh) -> np.ndarray | None:
    """The mesh's UV texture as linear float32 RGB, or None when it has no UVs or no image."""
    visual = mesh.visual
    if visual.kind != "texture" or getattr(visual, "uv", None) is None or len(visual.uv) != len(mesh.vertices):
        return None
    material = visual.material
    image = getattr(material, "image", None)
    if image is None:
        image = getattr(material, "baseColorTexture", None)
    if image is None:
        return None
    rgb = np.asarray(image.convert("RGB"), dtype=np.float64) / 255.0
    return np.ascontiguousarray(srgb_to_linear(rgb), dtype=np.float32)
