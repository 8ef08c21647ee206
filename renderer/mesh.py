"""The one place that reads meshes: load, clean, turn z-up into y-up, normalise, and look up colors.

Meshes are read with trimesh and *not* processed on load:
trimesh's vertex merging ignores vertex colors and uses an absolute tolerance, which would
blur per-vertex colors and collapse meshes modelled at the 1e-6 scale. Cleaning here uses
tolerances relative to the mesh's own size instead.

Colors are sRGB in [0, 1]. glTF base color factors are linear by that format's definition
and are converted; textures, vertex colors and face colors are taken as sRGB.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh
from PIL import Image

from renderer.color import linear_to_srgb, srgb_to_linear, to_uint8
from renderer.errors import InputError
from renderer.io import quiet_native_output
from renderer.limits import MAX_MESH_FACES, MAX_MESH_VERTICES
from renderer.mesh_header import MeshHeader, check_mesh_file
from renderer.scene import OBJECT_SIZE

MESH_EXTENSIONS = (".obj", ".ply", ".stl", ".off", ".glb", ".gltf")
UNCOLORED_GRAY = 0.5
# A face is degenerate when its area is below this fraction of the squared bounding-box diagonal.
DEGENERATE_AREA = 1e-14
# z-up to y-up: (x, y, z) -> (x, z, -y), a proper rotation, so winding and normals survive.
Z_UP_TO_Y_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


def load_mesh(path: str | Path, up: str = "y") -> trimesh.Trimesh:
    """Read a mesh file as one cleaned y-up mesh (scene parts flattened, colors and textures kept).

    The header is checked against the limits first (renderer/mesh_header.py); the readers run
    quietly, and a file that holds less than its header promises is refused, never read in part.
    """
    path = Path(path)
    if up not in ("y", "z"):
        raise InputError(f'up axis must be "y" or "z", got {up!r}', path)
    if path.suffix.lower() not in MESH_EXTENSIONS:
        raise InputError(f"unsupported mesh format {path.suffix or '(none)'!r}; use one of {', '.join(MESH_EXTENSIONS)}", path)
    if not path.is_file():
        raise InputError("file not found", path)
    header = check_mesh_file(path)
    mesh = _read_mesh(path)
    _check_complete(mesh, header, path)
    mesh = clean_mesh(mesh)
    if len(mesh.faces) == 0:
        raise InputError("mesh has no usable faces", path)
    if not (mesh.vertices.max(axis=0) > mesh.vertices.min(axis=0)).any():
        raise InputError("mesh has zero size", path)
    if up == "z":
        mesh.vertices = mesh.vertices @ Z_UP_TO_Y_UP.T
    return mesh


def missing_material_files(path: str | Path) -> list[str]:
    """The material libraries an OBJ names (`mtllib`) that are not beside it: trimesh then loads the mesh
    grey without a word, so callers warn with these names. Reads the first 64 KB, where `mtllib` lines stand."""
    path = Path(path)
    if path.suffix.lower() != ".obj" or not path.is_file():
        return []
    with open(path, "rb") as f:
        head = f.read(65536).decode("utf-8", "replace")
    names = [line.split(None, 1)[1].strip() for line in head.splitlines()
             if line.startswith("mtllib") and len(line.split(None, 1)) == 2]
    return [name for name in names if not (path.parent / name).is_file()]


def _read_mesh(path: Path) -> trimesh.Trimesh:
    """All triangle geometry of a file as one mesh, parts moved to their scene positions.

    trimesh reads first; where it fails or finds no faces, open3d's readers get a try on PLY and
    OFF files, since they accept some variants that trimesh does not. What the libraries print is
    kept out of the terminal; its first line goes into the refusal.
    """
    said: list[str] = []
    try:
        with quiet_native_output(said):
            scene = trimesh.load_scene(path, process=False)
            parts = [g for g in scene.dump() if isinstance(g, trimesh.Trimesh)]
    except Exception as exc:  # trimesh raises many exception types for corrupt files
        parts, problem = [], f"cannot read mesh ({type(exc).__name__}: {exc})"
    else:
        problem = "mesh has no faces"
    if not parts:
        fallback = _read_with_open3d(path, said) if path.suffix.lower() in (".ply", ".off") else None
        if fallback is None:
            reader_said = f"; the reader said: {said[0][:200]}" if said else ""
            raise InputError(problem + reader_said, path)
        return fallback
    return parts[0] if len(parts) == 1 else _concatenate(parts)


def _read_with_open3d(path: Path, said: list[str]) -> trimesh.Trimesh | None:
    """The file's triangles (and vertex colors) through open3d, or None when it has none either."""
    try:
        import open3d
    except (ImportError, OSError):  # open3d needs system libraries that may be missing
        return None
    try:
        with quiet_native_output(said):
            o3d_mesh = open3d.io.read_triangle_mesh(str(path), print_progress=False)
    except Exception:  # open3d raises on undecodable header text, among others
        return None
    faces = np.asarray(o3d_mesh.triangles)
    if len(faces) == 0 or any("fail" in line.lower() or "error" in line.lower() for line in said):
        return None  # open3d returns what it read before an error: a partial mesh is no mesh
    colors = to_uint8(np.asarray(o3d_mesh.vertex_colors)) if o3d_mesh.has_vertex_colors() else None
    return trimesh.Trimesh(np.asarray(o3d_mesh.vertices), faces, vertex_colors=colors, process=False)


def _check_complete(mesh: trimesh.Trimesh, header: MeshHeader, path: Path) -> None:
    """Refuse a mesh with fewer vertices or faces than its header promised, or more than the limits."""
    vertices, faces = len(mesh.vertices), len(mesh.faces)
    if (header.vertices is not None and vertices < header.vertices) or (header.faces is not None and faces < header.faces):
        raise InputError(f"file is cut: its header promises {header.vertices or '?'} vertices and {header.faces or '?'} "
                         f"faces, the file holds {vertices} and {faces}", path)
    if vertices > MAX_MESH_VERTICES or faces > MAX_MESH_FACES:
        raise InputError(f"mesh has {vertices:,} vertices and {faces:,} faces; meshes are read up to "
                         f"{MAX_MESH_VERTICES:,} and {MAX_MESH_FACES:,}", path)


def _concatenate(parts: list[trimesh.Trimesh]) -> trimesh.Trimesh:
    """Flatten scene parts into one mesh, keeping textures (packed into one atlas by trimesh) or colors.

    trimesh drops all colors when parts of different kinds are mixed, so mixed parts all
    become vertex colors first (textures sampled at the vertices, uncolored parts gray); and
    it mis-multiplies glTF base color factors into the atlas, so those are baked in first.
    """
    mixed = len({p.visual.kind for p in parts}) > 1
    for p in parts:
        if p.visual.kind == "texture":
            p.visual = p.visual.to_color() if mixed else _bake_base_color_factor(p.visual)
        elif p.visual.kind is None and mixed:
            p.visual = trimesh.visual.ColorVisuals(p, vertex_colors=to_uint8(np.full((len(p.vertices), 3), UNCOLORED_GRAY)))
    return trimesh.util.concatenate(parts)


def _bake_base_color_factor(visual: trimesh.visual.TextureVisuals) -> trimesh.visual.TextureVisuals:
    """The same look with a glTF material's linear color factor multiplied into its texture."""
    material = visual.material
    if not isinstance(material, trimesh.visual.material.PBRMaterial):
        return visual
    if material.baseColorTexture is None or material.baseColorFactor is None:
        return visual
    texels = np.asarray(material.baseColorTexture.convert("RGBA"), dtype=np.float64) / 255.0
    factor = _rgb01(material.baseColorFactor)
    texels[..., :3] = linear_to_srgb(srgb_to_linear(texels[..., :3]) * factor)
    baked = trimesh.visual.material.PBRMaterial(baseColorTexture=Image.fromarray(to_uint8(texels)))
    return trimesh.visual.TextureVisuals(uv=visual.uv, material=baked)


def clean_mesh(mesh: trimesh.Trimesh) -> trimesh.Trimesh:
    """A copy without faces touching NaN/Inf vertices, degenerate faces and duplicate faces."""
    mesh = mesh.copy()
    faces = np.asarray(mesh.faces)
    if len(faces) == 0:
        return mesh
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    keep = np.isfinite(vertices).all(axis=1)[faces].all(axis=1)
    vertices = vertices / _magnitude(vertices)  # areas of meshes near the float limit would overflow
    finite = vertices[faces[keep].ravel()]
    diag2 = float(np.sum(np.ptp(finite, axis=0) ** 2)) if len(finite) else 0.0
    tri = np.nan_to_num(vertices[faces], nan=0.0, posinf=0.0, neginf=0.0)  # their faces are dropped already
    area2 = np.sum(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]) ** 2, axis=1)  # (2 * area)^2
    keep &= area2 > (2.0 * DEGENERATE_AREA * diag2) ** 2
    # Duplicates: the same three positions, whatever the vertex indices or their order.
    _, position_id = np.unique(np.nan_to_num(vertices), axis=0, return_inverse=True)
    keys = np.sort(position_id.reshape(-1)[faces], axis=1)
    _, first = np.unique(keys[keep], axis=0, return_index=True)
    unique = np.zeros(len(faces), dtype=bool)
    unique[np.flatnonzero(keep)[first]] = True
    mesh.update_faces(unique)
    mesh.remove_unreferenced_vertices()
    return mesh


def _magnitude(vertices: np.ndarray) -> float:
    """The largest finite coordinate's size (1 when there is none): dividing by it keeps sums finite."""
    finite = np.abs(vertices[np.isfinite(vertices)])
    largest = float(finite.max()) if finite.size else 0.0
    return largest if largest > 0.0 else 1.0


def normalise_mesh(mesh: trimesh.Trimesh) -> trimesh.Trimesh:
    """A copy in object coordinates (renderer/transform.py): longest side OBJECT_SIZE, centred on x and z, min y = 0."""
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    if len(mesh.faces) == 0 or not np.isfinite(vertices).all():
        raise InputError("mesh has no faces or non-finite vertices; clean it first")
    vertices = vertices / _magnitude(vertices)  # sides of meshes near the float limit would overflow
    lo, hi = vertices.min(axis=0), vertices.max(axis=0)
    size = float((hi - lo).max())
    if size <= 0.0:
        raise InputError("mesh has zero size")
    anchor = np.array([0.5 * (lo[0] + hi[0]), lo[1], 0.5 * (lo[2] + hi[2])])
    out = mesh.copy()
    out.vertices = (vertices - anchor) * (OBJECT_SIZE / size)
    return out


# --- material colors at surface points -----------------------------------------------------


def mesh_colors_at(mesh: trimesh.Trimesh, points: np.ndarray, face_ids: np.ndarray) -> np.ndarray:
    """sRGB colors (M, 3) of the mesh's material at `points` (M, 3) lying on faces `face_ids` (M,).

    Texture lookup (nearest texel, wrapping UVs), else barycentric vertex colors, else face
    colors, else uniform gray. Points slightly off their face are snapped into it.
    """
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    face_ids = np.asarray(face_ids, dtype=np.int64).reshape(-1)
    visual = mesh.visual
    kind = visual.kind
    if kind == "texture":
        return _texture_colors(mesh, points, face_ids)
    if kind == "vertex":
        corner_colors = _rgb01(visual.vertex_colors)[mesh.faces[face_ids]]  # (M, 3, 3)
        return np.einsum("mk,mkc->mc", _barycentric(mesh, points, face_ids), corner_colors)
    if kind == "face":
        return _rgb01(visual.face_colors)[face_ids]
    return np.full((len(points), 3), UNCOLORED_GRAY)


def _barycentric(mesh: trimesh.Trimesh, points: np.ndarray, face_ids: np.ndarray) -> np.ndarray:
    """Barycentric coordinates (M, 3) of points in their faces, clamped into the face and summing to 1."""
    triangles = np.asarray(mesh.vertices, dtype=np.float64)[mesh.faces[face_ids]]
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):  # degenerate faces: replaced just below
        bary = trimesh.triangles.points_to_barycentric(triangles, points)
    bary[~np.isfinite(bary).all(axis=1)] = 1.0 / 3.0  # NaN or infinite: the face's centre color
    bary = np.clip(bary, 0.0, 1e6)  # slivers give huge finite weights; bounded, their sum cannot overflow
    total = bary.sum(axis=1, keepdims=True)
    return np.where(total > 0.0, bary / np.where(total > 0.0, total, 1.0), 1.0 / 3.0)


def _texture_colors(mesh: trimesh.Trimesh, points: np.ndarray, face_ids: np.ndarray) -> np.ndarray:
    """Colors from a material: its image at interpolated UVs, times its base color.

    glTF (PBR): linear base color factor times the decoded sRGB texture. OBJ (simple
    material): the texture alone when there is one (as Blender reads OBJ), else the diffuse color.
    """
    visual, material = mesh.visual, mesh.visual.material
    is_pbr = isinstance(material, trimesh.visual.material.PBRMaterial)
    image = material.baseColorTexture if is_pbr else getattr(material, "image", None)
    if is_pbr:
        factor = material.baseColorFactor
    else:
        factor = getattr(material, "diffuse", None) if image is None else None
    base = np.ones(3) if factor is None else _rgb01(factor)
    has_uv = visual.uv is not None and len(visual.uv) == len(mesh.vertices)
    if image is None or not has_uv:
        color = linear_to_srgb(base) if is_pbr else base
        return np.tile(color, (len(points), 1))
    corner_uv = np.asarray(visual.uv, dtype=np.float64)[mesh.faces[face_ids]]
    texels = _sample_nearest(image, np.einsum("mk,mkc->mc", _barycentric(mesh, points, face_ids), corner_uv))
    return linear_to_srgb(srgb_to_linear(texels) * base) if is_pbr else texels * base


def _sample_nearest(image: Image.Image, uv: np.ndarray) -> np.ndarray:
    """sRGB texels (M, 3) at UVs (v = 0 is the bottom row), repeating outside [0, 1]."""
    pixels = np.asarray(image.convert("RGB"), dtype=np.float64) / 255.0
    height, width = pixels.shape[:2]
    uv = np.nan_to_num(uv)
    cols = np.floor(uv[:, 0] * width).astype(np.int64) % width
    rows = np.floor((1.0 - uv[:, 1]) * height).astype(np.int64) % height
    return pixels[rows, cols]


def _rgb01(colors: np.ndarray) -> np.ndarray:
    """RGB part of trimesh colors (8-bit RGBA, or floats already in [0, 1]) as floats in [0, 1]."""
    c = np.asarray(colors)
    rgb = c[..., :3].astype(np.float64)
    return rgb / 255.0 if c.dtype.kind in "ui" else rgb
