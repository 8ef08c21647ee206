"""Write the demo asset assets/demo/chair.obj: a generated chair in the `default` appearance.

Run `python -m renderer.objects.demo [output.obj]`; the same code always writes the same file,
so the asset is traceable to this seed.
"""

from __future__ import annotations

import sys
from pathlib import Path

from renderer.io import atomic_path
from renderer.objects.appearance import apply_appearance
from renderer.objects.generate import generate_object

DEMO_CATEGORY = "chair"
DEMO_SEED = 10  # a swivel chair: wooden seat and slatted back, metal armrests and star base (train split)
DEMO_PATH = Path(__file__).resolve().parents[2] / "assets" / "demo" / "chair.obj"


def write_demo(path: Path = DEMO_PATH) -> Path:
    """Generate the demo chair, color it with per-part materials, and save it as OBJ with vertex colors."""
    obj = generate_object(DEMO_CATEGORY, DEMO_SEED)
    mesh, _, _ = apply_appearance(obj, "default", DEMO_SEED, "train")
    with atomic_path(path) as tmp:
        mesh.export(tmp, file_type="obj", include_normals=False, include_texture=False)
    return path


if __name__ == "__main__":
    print(write_demo(Path(sys.argv[1]) if len(sys.argv) > 1 else DEMO_PATH))
