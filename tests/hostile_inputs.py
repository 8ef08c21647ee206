"""A compact generator of hostile inputs for the command line: broken meshes, scene files, images,
weight files and options. Each case is a command and the files it reads; the fuzz test runs each in
its own process and checks exit 2, one line, no traceback, bounded memory and nothing written.
"""

from __future__ import annotations

import io
import json
import os
import pickle
import struct
import subprocess
import sys
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
DEMO_SCENE = REPO / "assets" / "demo" / "scene.json"
DEMO_MESH = REPO / "assets" / "demo" / "chair.obj"
SHIPPED_WEIGHTS = REPO / "assets" / "models" / "nvrplus_compact.safetensors"


@dataclass
class Case:
    """One hostile input: `argv` after the program name, run in a folder holding `files`."""

    name: str
    argv: list[str]
    files: dict[str, bytes] = field(default_factory=dict)
    program: str = "nvr"


@dataclass
class Outcome:
    code: int
    stderr: str
    stdout: str
    peak_rss_mb: float
    written: list[str]


ADDRESS_SPACE_LIMIT = 4 << 30  # a regression that allocates gigabytes fails fast instead of swamping the machine
MEASURE = Path(__file__).resolve().parent / "run_measured.py"


def run_case(case: Case, folder: Path, display: str | None = None) -> Outcome:
    """Write the case's files into `folder`, run the command there (the command line under an address-space
    limit; the editor without, as software OpenGL maps much), and report what it did."""
    for name, data in case.files.items():
        (folder / name).parent.mkdir(parents=True, exist_ok=True)
        (folder / name).write_bytes(data)
    before = {p: p.stat().st_mtime_ns for p in folder.rglob("*")}
    program = [sys.executable, "-m", "app.cli"] if case.program == "nvr" else [sys.executable, "-m", "app.editor.main"]
    env = {**os.environ, "PYTHONPATH": str(REPO), "XDG_STATE_HOME": str(folder / ".state"), "NVR_EDITOR_TIMEOUT": "100"}
    if display:
        env["DISPLAY"] = display
    limit = ["--limit", str(ADDRESS_SPACE_LIMIT)] if case.program == "nvr" else []
    result = folder / ".measured.json"
    completed = subprocess.run([sys.executable, str(MEASURE), str(result), *limit, "--", *program, *case.argv],
                               cwd=folder, capture_output=True, text=True, env=env, errors="replace")
    measured = json.loads(result.read_text())
    ours = (".state", ".measured.json")
    written = sorted(str(p.relative_to(folder)) for p in folder.rglob("*")
                     if p.is_file() and before.get(p) != p.stat().st_mtime_ns and p.relative_to(folder).parts[0] not in ours)
    return Outcome(measured["code"], completed.stderr, completed.stdout, measured["peak_rss_mb"], written)


# --- hostile files ------------------------------------------------------------------------------------


def random_bytes(n: int, seed: int = 0) -> bytes:
    return np.random.default_rng(seed).integers(0, 256, n, dtype=np.uint8).tobytes()


def cube_mesh() -> tuple[np.ndarray, np.ndarray]:
    v = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], dtype=np.float32)
    f = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                  [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]], dtype=np.int32)
    return v, f


def binary_ply(vertices: np.ndarray, faces: np.ndarray, claim_vertices: int | None = None) -> bytes:
    header = (f"ply\nformat binary_little_endian 1.0\nelement vertex {claim_vertices or len(vertices)}\n"
              "property float x\nproperty float y\nproperty float z\n"
              f"element face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n").encode()
    body = vertices.astype("<f4").tobytes() + b"".join(struct.pack("<B3i", 3, *f) for f in faces)
    return header + body


def ascii_ply(vertices: np.ndarray, faces: np.ndarray, claim_vertices: int | None = None) -> bytes:
    lines = ["ply", "format ascii 1.0", f"element vertex {claim_vertices or len(vertices)}",
             "property float x", "property float y", "property float z", f"element face {len(faces)}",
             "property list uchar int vertex_indices", "end_header"]
    lines += [" ".join(str(c) for c in v) for v in vertices] + ["3 " + " ".join(str(i) for i in f) for f in faces]
    return ("\n".join(lines) + "\n").encode()


def off_mesh(vertices: np.ndarray, faces: np.ndarray, claim_vertices: int | None = None) -> bytes:
    lines = ["OFF", f"{claim_vertices or len(vertices)} {len(faces)} 0"]
    lines += [" ".join(str(c) for c in v) for v in vertices] + ["3 " + " ".join(str(i) for i in f) for f in faces]
    return ("\n".join(lines) + "\n").encode()


def obj_mesh(vertices: np.ndarray, faces: np.ndarray) -> bytes:
    lines = [f"v {v[0]} {v[1]} {v[2]}" for v in vertices] + [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in faces]
    return ("\n".join(lines) + "\n").encode()


def binary_stl(vertices: np.ndarray, faces: np.ndarray, claim_faces: int | None = None) -> bytes:
    body = b"".join(struct.pack("<12fH", 0, 0, 0, *vertices[f].ravel(), 0) for f in faces)
    return b"\0" * 80 + struct.pack("<I", claim_faces or len(faces)) + body


def glb_claiming(json_length: int) -> bytes:
    """A GLB whose JSON chunk header claims `json_length` bytes but holds a few."""
    chunk = b'{"asset":{"version":"2.0"}}  '
    return b"glTF" + struct.pack("<II", 2, 12 + 8 + len(chunk)) + struct.pack("<I", json_length) + b"JSON" + chunk


def scene_json(**changes) -> dict:
    scene = json.loads(DEMO_SCENE.read_text())
    scene["objects"][0]["mesh"] = "chair.obj"
    for key, value in changes.items():
        scene[key] = value
    return scene


def scene_with_object(**object_changes) -> bytes:
    scene = scene_json()
    scene["objects"][0].update(object_changes)
    return json.dumps(scene).encode()


def npz_bytes(**arrays) -> bytes:
    buffer = io.BytesIO()
    np.savez_compressed(buffer, **arrays)
    return buffer.getvalue()


def weights_with_config(**config_changes) -> bytes:
    """The shipped weights with the stored network config changed (tensors untouched)."""
    from safetensors import safe_open
    from safetensors.numpy import save

    with safe_open(str(SHIPPED_WEIGHTS), framework="numpy") as f:
        metadata = dict(f.metadata())
        tensors = {k: f.get_tensor(k) for k in f.keys()}
    config = json.loads(metadata["config"])
    config.update(config_changes)
    metadata["config"] = json.dumps(config)
    return save(tensors, metadata=metadata)


def weights_with_header(header: dict) -> bytes:
    text = json.dumps(header).encode()
    return struct.pack("<Q", len(text)) + text


def pickle_disguised() -> bytes:
    class Boom:
        def __reduce__(self):
            return (os.system, ("touch PWNED",))

    return pickle.dumps(Boom())


def broken_zip() -> bytes:
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w") as z:
        z.writestr("rgba.npy", b"\x93NUMPY garbage")
    return buffer.getvalue()


# --- the cases ---------------------------------------------------------------------------------------


def mesh_cases() -> list[Case]:
    v, f = cube_mesh()
    big_claim = 10**9
    files = {
        "random.off": random_bytes(4096, 1),
        "random.ply": random_bytes(4096, 2),
        "random.obj": random_bytes(4096, 3),
        "random.stl": random_bytes(4096, 4),
        "random.glb": random_bytes(4096, 5),
        "empty.obj": b"",
        "huge_header.ply": binary_ply(v, f, claim_vertices=big_claim),
        "huge_header_ascii.ply": ascii_ply(v, f, claim_vertices=big_claim),
        "huge_header.off": off_mesh(v, f, claim_vertices=big_claim),
        "huge_header.stl": binary_stl(v, f, claim_faces=big_claim),
        "cut.ply": binary_ply(v, f)[: len(binary_ply(v, f)) // 2 + 40],
        "cut_ascii.ply": ascii_ply(v, f)[: len(ascii_ply(v, f)) * 2 // 3],
        "cut.off": off_mesh(v, f)[: len(off_mesh(v, f)) * 2 // 3],
        "nan.obj": obj_mesh(np.full_like(v, np.nan), f),
        "infinite_coords.obj": obj_mesh((v - 0.5) * np.float32(np.inf), f),
        "cut_long.off": off_mesh(v + 0.123456789, f)[: len(off_mesh(v + 0.123456789, f)) * 4 // 5],
        "lying_json.glb": glb_claiming(2_000_000_000),
        "missing_buffer.gltf": json.dumps({"asset": {"version": "2.0"}, "buffers": [{"uri": "nothere.bin", "byteLength": 10**9}]}).encode(),
        "text.stl": b"solid x\nfacet normal 0 0 0\nouter loop\nvertex 1 2\nendloop\n",
    }
    return [Case(f"voxelize {name}", ["voxelize", name, "-o", "out.npz"], {name: data}) for name, data in files.items()]


def scene_cases() -> list[Case]:
    mesh = DEMO_MESH.read_bytes()
    deep = ("[" * 100_000 + "]" * 100_000).encode()
    long_digits = b'{"version": 1, "object": {"mesh": "chair.obj"}, "image_size": ' + b"9" * 100_000 + b"}"
    big_voxels = npz_bytes(rgba=np.zeros((900, 900, 900, 4), np.uint8))
    scenes = {
        "long_name.json": scene_with_object(mesh="a" * 300 + ".obj"),
        "surrogate.json": b'{"version": 1, "object": {"mesh": "x\\ud800.obj"}}',
        "deep.json": deep,
        "digits.json": long_digits,
        "size4096.json": json.dumps(scene_json(image_size=4096)).encode(),
        "big_voxels.json": scene_with_object(voxels="big.npz"),
        "bad_voxels.json": scene_with_object(voxels="bad.npz"),
        "dir_mesh.json": scene_with_object(mesh="."),
        "float_resolution.json": scene_with_object(resolution=1e300),
        "string_scale.json": scene_with_object(scale="big"),
        "huge_paint.json": scene_with_object(paint=[{"target": "region", "color": [1, 0, 0], "seed": [10**30, 0, 0]}]),
        "binary.json": random_bytes(2048, 7),
        "huge_file.json": b'{"version": 1, "pad": "' + b" " * (80 << 20) + b'"}',
    }
    extra = {"chair.obj": mesh, "big.npz": big_voxels, "bad.npz": broken_zip()}
    return [Case(f"info {name}", ["info", name], {name: data, **extra}) for name, data in scenes.items()]


def vox_cases() -> list[Case]:
    header = b"VOX " + struct.pack("<i", 150)
    files = {
        "random.vox": random_bytes(4096, 10),
        "cut.vox": header + struct.pack("<4sii", b"MAIN", 0, 5000) + b"SIZE",
        "lying_count.vox": header + struct.pack("<4sii", b"MAIN", 0, 40) + struct.pack("<4sii3i", b"SIZE", 12, 0, 4, 4, 4)
        + struct.pack("<4siii", b"XYZI", 4, 0, 10**9),
    }
    return [Case(f"import-vox {name}", ["import-vox", name, "-o", "scene.json"], {name: data}) for name, data in files.items()]


def image_cases() -> list[Case]:
    from PIL import Image

    png = io.BytesIO()
    Image.new("RGB", (8, 8)).save(png, format="PNG")
    images = {
        "random.png": random_bytes(4096, 8),
        "cut.png": png.getvalue()[:40],
        "bomb.png": _png_bomb(),
    }
    mesh = DEMO_MESH.read_bytes()
    return [Case(f"capture {name}", ["capture", "chair.obj", name, "-o", "cap.json"], {name: data, "chair.obj": mesh})
            for name, data in images.items()]


def _png_bomb() -> bytes:
    """A PNG whose header claims 100,000 x 100,000 pixels (its data is tiny)."""
    import zlib

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", 100_000, 100_000, 8, 2, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(b"\0" * 1000)) + chunk(b"IEND", b""))


def weight_cases() -> list[Case]:
    scene = json.dumps(scene_json()).encode()
    mesh = DEMO_MESH.read_bytes()
    weights = {
        "truncated.safetensors": SHIPPED_WEIGHTS.read_bytes()[:5000],
        "lying.safetensors": weights_with_header({"x": {"dtype": "F32", "shape": [10**6, 10**6], "data_offsets": [0, 4 * 10**12]}}),
        "pickle.safetensors": pickle_disguised(),
        "huge_config.safetensors": weights_with_config(latent_channels=10**6),
        "negative_config.safetensors": weights_with_config(latent_channels=-3),
    }
    return [Case(f"render --model {name}", ["render", "scene.json", "-o", "out.png", "--renderer", "nvr+", "--model", name],
                 {name: data, "scene.json": scene, "chair.obj": mesh}) for name, data in weights.items()]


def option_cases() -> list[Case]:
    scene = {"scene.json": json.dumps(scene_json()).encode(), "chair.obj": DEMO_MESH.read_bytes()}
    cases = [
        Case("render --size 100000", ["render", "scene.json", "-o", "out.png", "--size", "100000"], scene),
        Case("render --size 5000", ["render", "scene.json", "-o", "out.png", "--size", "5000"], scene),
        Case("render --size x", ["render", "scene.json", "-o", "out.png", "--size", "x"], scene),
        Case("render --spp -1", ["render", "scene.json", "-o", "out.png", "--renderer", "pathtrace", "--spp", "-1"], scene),
        Case("render --device quantum", ["render", "scene.json", "-o", "out.png", "--renderer", "nvr+", "--device", "quantum"], scene),
        Case("render unknown option", ["render", "scene.json", "-o", "out.png", "--bogus"], scene),
        Case("voxelize --res 100000", ["voxelize", "chair.obj", "-o", "out.npz", "--res", "100000"], scene),
        Case("data generate --workers 0", ["data", "generate", "--out", "d", "--objects", "1", "--workers", "0"]),
        Case("data generate --workers -2", ["data", "generate", "--out", "d", "--objects", "1", "--workers", "-2"]),
        Case("data generate --seed -1", ["data", "generate", "--out", "d", "--objects", "1", "--seed", "-1"]),
        Case("data generate --objects 0", ["data", "generate", "--out", "d", "--objects", "0"]),
        Case("data generate --size 100000", ["data", "generate", "--out", "d", "--objects", "1", "--size", "100000"]),
        Case("data generate --spp 0", ["data", "generate", "--out", "d", "--objects", "1", "--spp", "0"]),
        Case("data generate --categories spaceship", ["data", "generate", "--out", "d", "--objects", "1", "--categories",
                                                       "spaceship"]),
        Case("data generate --lighting moon", ["data", "generate", "--out", "d", "--objects", "1", "--lighting", "moon"]),
        Case("data generate --shard 3/2", ["data", "generate", "--out", "d", "--objects", "1", "--shard", "3/2"]),
        Case("data recolor of no data set", ["data", "recolor", "d", "--out", "e"], {"d/config.json": b"{}"}),
        Case("data recolor of a broken record", ["data", "recolor", "d", "--out", "e"],
             {"d/config.json": json.dumps({"config": {"setting": "default"}}).encode(),
              "d/records/o00000.json": b'{"object": {"setting": "default"}}'}),
        Case("data recolor --res 1000", ["data", "recolor", "d", "--out", "e", "--res", "1000"],
             {"d/config.json": json.dumps({"config": {"setting": "default"}}).encode()}),
        Case("data recolor --res of a record without its mesh's seeds", ["data", "recolor", "d", "--out", "e", "--res", "8"],
             {"d/config.json": json.dumps({"config": {"setting": "single", "resolution": 4}}).encode(),
              "d/records/o00000.json": json.dumps({"object": {
                  "index": 0, "setting": "single", "floor_color": [0.5, 0.5, 0.5], "voxels": "objects/o00000.npz",
                  "source_image": "objects/o00000_source.png", "source_camera": "objects/o00000_source_camera.json",
                  "mirror_symmetry_used": False}, "samples": []}).encode(),
              "d/objects/o00000.npz": npz_bytes(rgba=np.full((4, 4, 4, 4), 255, dtype=np.uint8))}),
        Case("capture --light 1,2", ["capture", "chair.obj", "photo.png", "-o", "s.json", "--light", "1,2"], scene),
        Case("capture --light nan", ["capture", "chair.obj", "photo.png", "-o", "s.json", "--light", "1,nan,2"], scene),
        Case("train --lr inf", ["train", "--data", "d", "--out", "run", "--lr", "inf"]),
        Case("train --lr 1e30", ["train", "--data", "d", "--out", "run", "--lr", "1e30"]),
        Case("train --set latent_channels", ["train", "--data", "d", "--out", "run", "--set", "latent_channels=1000000"]),
        Case("train --set bogus", ["train", "--data", "d", "--out", "run", "--set", "no_such_field=3"]),
        Case("train --device quantum", ["train", "--data", "d", "--out", "run", "--device", "quantum"]),
        Case("train --threads -1", ["train", "--data", "d", "--out", "run", "--threads", "-1"]),
        Case("train --perceptual-crop -5", ["train", "--data", "d", "--out", "run", "--perceptual-crop", "-5"]),
        Case("eval --limit -1", ["eval", "--data", "d", "--report", "r.md", "--limit", "-1"]),
        Case("eval --resolution-study 1000", ["eval", "--data", "d", "--report", "r.md", "--resolution-study", "1000"]),
        Case("eval --resolution-study 0", ["eval", "--data", "d", "--report", "r.md", "--resolution-study", "0,50"]),
    ]
    return cases


def editor_cases() -> list[Case]:
    scene = json.dumps(scene_json()).encode()
    return [
        Case("editor --model pickle", ["scene.json", "--model", "p.safetensors", "--frames", "2"],
             {"scene.json": scene, "chair.obj": DEMO_MESH.read_bytes(), "p.safetensors": pickle_disguised()}, "nvr-editor"),
        Case("editor random-bytes mesh", ["scene.json", "--frames", "2"],
             {"scene.json": scene, "chair.obj": random_bytes(4096, 9)}, "nvr-editor"),
        Case("editor broken scene", ["scene.json", "--frames", "2"], {"scene.json": b"{not json"}, "nvr-editor"),
    ]


def all_cases() -> list[Case]:
    return mesh_cases() + scene_cases() + vox_cases() + image_cases() + weight_cases() + option_cases() + editor_cases()


if __name__ == "__main__":  # survey: run every case and print what it did
    import tempfile

    only = sys.argv[1:]
    for case in all_cases():
        if only and not any(o in case.name for o in only):
            continue
        with tempfile.TemporaryDirectory() as tmp:
            o = run_case(case, Path(tmp), os.environ.get("DISPLAY"))
        lines = [line for line in (o.stdout + o.stderr).splitlines() if line.strip()]
        ok = o.code == 2 and len(lines) == 1 and not o.written and o.peak_rss_mb < 1024
        print(f"{'ok ' if ok else 'BAD'} {case.name:40s} exit {o.code} lines {len(lines)} rss {o.peak_rss_mb:6.0f} MB "
              f"written {o.written} | {lines[-1][:150] if lines else ''}", flush=True)
