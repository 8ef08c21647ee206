"""The input limits of NVR Studio, stated once. Every reader checks them before it allocates, so a
hostile or broken file is refused in one line with the limit named, within a bounded amount of memory.

The figures are measured on the project's 2-core, 24 GB machine (docs/robustness.md says how).
"""

from __future__ import annotations

# Images. The networks render 256 px; the splat, the voxel shader and the path tracer render any size
# up to MAX_IMAGE_SIZE. At 2048 px the voxel shader, the most memory-hungry of them, peaks at 1.2 GB
# (4096 px needed 3.4 GB), so 2048 is the largest size whose render stays near one gigabyte.
MIN_IMAGE_SIZE = 16
MAX_IMAGE_SIZE = 2048

# Object voxels per side: 256^3 RGBA floats are 268 MB, the largest grid a CPU edit loop can hold. Meshes are
# voxelised at DEFAULT_RESOLUTION unless a scene or a command says otherwise: at 200^3 against 100^3 the shipped NVR+
# lost a fifth of its error on the test split (docs/results.md, "Design choices").
MIN_RESOLUTION = 4
MAX_RESOLUTION = 256
DEFAULT_RESOLUTION = 200

# Meshes: a 5 M-face mesh is a 250 MB text OBJ and voxelises in seconds; beyond that a mesh is
# decimated first. Counts are read from the file's header (PLY, OFF, STL, GLB) before the body.
MAX_MESH_FILE_BYTES = 300 * 2**20
MAX_MESH_VERTICES = 5_000_000
MAX_MESH_FACES = 5_000_000

# Files the product reads whole: scene files and camera files (a scene with 10,000 paint strokes is
# about 1 MB), data set manifests (20,000 samples are about 15 MB), object voxel files (a 256^3 grid
# compressed), weight files (the paper's 79 M-parameter network is 316 MB in float32).
MAX_JSON_BYTES = 64 * 2**20
MAX_NUMBER_DIGITS = 50  # no valid number needs more digits (a float has 17 significant ones)
MAX_VOXEL_FILE_BYTES = 300 * 2**20
MAX_WEIGHT_PARAMETERS = 200_000_000

# Paths inside scene files: the usual file system limits (Linux: 4096 per path, 255 bytes per name).
MAX_PATH_CHARACTERS = 4096
MAX_NAME_BYTES = 255

# Photos larger than this are downscaled while they are decoded; beyond MAX_PHOTO_PIXELS a file is
# refused as a decompression bomb (PIL checks the header before decoding).
MAX_PHOTO_SIDE = 4096
MAX_TEXTURE_SIDE = 1024  # a floor texture's long side, after reducing it while decoding: one repeat is a few hundred pixels on screen
MAX_MAP_SIDE = 8192  # widest environment map read: 8192 x 4096 floats are 400 MB while the map is reduced
MAX_PHOTO_PIXELS = 400_000_000
MAX_OBJECTS = 16  # objects a scene holds: each keeps its own voxels and shader stages (a 200^3 object's voxels take 128 MB)
MAX_PAINT_STROKES = 10_000  # paint operations a scene holds: far more than anyone paints by hand, and few enough to parse at once
