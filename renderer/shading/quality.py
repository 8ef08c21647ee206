"""The voxel shader's tuned values and its quality settings (how finely it samples its dearest terms).

Each value was chosen by measuring the shader and the shipped NVR+ against the path tracer on the test sets;
the figures are in docs/results.md, "Design choices, measured" (DC below) and "Measurements behind the code" (MC).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from renderer.errors import InputError

THIN_LEVEL = 0.35  # voxels above a thin part's core where its surface is drawn (if more than SURFACE_LEVEL)
SURFACE_LEVEL = 0.8  # voxels from the nearest occupied voxel centre to the drawn surface (the hull is fatter than the mesh)
DISTANCE_SIGMA = 1.0  # voxels: blur of the distance field the surface is drawn from (smooth, not beaded)
NORMAL_SIGMA = 1.5  # voxels: blur of the distance field the normals come from (no staircases; wider blurs err more: DC)
# Normals are averaged over a disc of the surface's tangent plane: a face a few degrees off a voxel axis is a staircase
# of long treads that the blur above cannot flatten (bands of light across a leaning chair back). Samples whose
# normal is more than about 45 degrees from the point's own are left out, so edges between faces stay sharp (DC).
NORMAL_DISC = 16.0  # voxels: the disc's radius
NORMAL_RINGS = 2  # rings of 8 samples on it
NORMAL_AGREE = 0.7  # a sample counts by how far the cosine to the point's normal exceeds this
BROAD_SIGMA = 2.5  # voxels: occupancy blur for ambient occlusion
BROAD_SCALE = 0.5  # the broad occupancy is stored at half resolution
BLUR_TRUNCATE = 2.5  # gaussian kernels reach this many sigmas
CROP_MARGIN = 6  # voxels around the object's box (blur and occlusion reach)
# Per side of the light square: shadow maps and the direct-light sum. 3 x 3 instead of 4 x 4 takes a quarter off the
# light stage at a negligible cost in error (DC).
LIGHT_POINTS = 3
SHADOW_MAP_SIZE = 96  # texels per side
# Radius of the sphere around each occluder that the shadow maps draw, in sides of the block it stands for. The hull
# is fatter than the mesh, and a thin part's band of voxels most of all: the drawn surface's distance cast lattices'
# floor shadows too dark; 0.2 erred least of the radii tried (MC).
OCCLUDER_RADIUS = 0.2
# Each occluder stands for the occupied voxels of a block, at their mean centre, the blocks about 1 / OCCLUDER_CELLS of
# the object box on a side (2^3 of the product's 200^3 voxels; an object voxelised at 100^3 or merged in pairs casts
# from its own voxels), and covers its block's square in the maps. A quarter of the occluders casts shadows as good
# for the NVR+, whose data's shadows 100^3 voxels cast, and the light stage is quicker (DC).
OCCLUDER_CELLS = 100
# The shadow maps' offsets and biases below are in sides of an occluder's block (OCCLUDER_CELLS), to which the maps
# know an occluder's place; half as far erred more, further changed nothing (DC).
SHADOW_NORMAL_OFFSET = 1.0  # how far along the normal an object point is moved before the shadow maps are read
SHADOW_GRAZING_OFFSET = 1.5  # how much further, times the sine of the angle between the normal and the light
SHADOW_BIAS = 0.5  # how much nearer the light an occluder must be than the moved point to shadow it
FLOOR_SHADOW_BIAS = 0.25  # the same for a floor point
FLOOR_SHADOW_STEP = 0.025  # world units between the floor points the shadow maps are read at
OCCLUSION_DISTANCES = np.array([1.5, 3.0, 6.0, 12.0], dtype=np.float32)  # voxels along the normal
OCCLUSION_WEIGHTS = np.array([0.35, 0.3, 0.25, 0.2], dtype=np.float32)
# Beyond the broad occupancy's reach, the sky a hollow hides (the inside of a cup, a pipe, a box seen into its
# opening): cones of FAR_CONE_HALF_ANGLE, one along the normal and FAR_RING_CONES at FAR_RING_TILT from it, traced
# from FAR_START voxels through the solid occupancy averaged over blocks of FAR_BLOCKS voxels (voxel cone tracing).
FAR_BLOCKS = (4, 8, 16, 32)
FAR_CONE_HALF_ANGLE = 30.0  # degrees
FAR_RING_CONES = 6
FAR_RING_TILT = 50.0  # degrees
FAR_START = 8.0  # voxels
# A share of the sky the cones see at or above FAR_FULL_SKY counts as all of it: only a hollow's deep inside is darkened.
# The cones are coarse (a chair's parts read as half the sky blocked where they hide less), and the shipped NVR+ was
# trained without this term, which at full strength it takes badly (DC).
FAR_FULL_SKY = 0.5
# The far sky changes slowly over a surface: it is traced at one point of each block of FAR_SHARE_PIXELS^2 pixels (at
# 256^2; as many voxels across at any size), and taken by the block's points within FAR_SHARE_DISTANCE voxels of that
# one whose normals agree to FAR_SHARE_COSINE.
FAR_SHARE_PIXELS = 2
FAR_SHARE_DISTANCE = 8.0
FAR_SHARE_COSINE = 0.8
FLOOR_OCCLUSION_DISTANCES = np.array([2.0, 5.0, 10.0, 20.0], dtype=np.float32)  # voxels straight up
FLOOR_OCCLUSION_WEIGHTS = np.array([0.3, 0.3, 0.25, 0.2], dtype=np.float32)
# Under an environment the floor's sky is traced through the far cones too (a table's top hides the zenith from the
# ground under it, 35 voxels up and more), at points FLOOR_SKY_PIXELS apart at 256^2, from FLOOR_SKY_START voxels.
FLOOR_SKY_PIXELS = 4
FLOOR_SKY_START = 4.0
BLOCKED_SKY_LIGHT = 0.35  # share of the ambient light a blocked sky direction still brings (the lit object)
FLOOR_BOUNCE = 1.0  # weight of the light the floor sends back up onto the object (0: none)
FLOOR_BELOW_LIT = 0.5  # share of the direct light the floor under an object point gets (its shadow falls there)
# A pixel shows the texture averaged over its footprint: a point takes the colors of the voxels around it, weighted
# by a Gaussian centred on the point of COLOR_SPREAD pixel sides at its depth, not its voxel's color alone (the spread
# that erred least, DC). At least COLOR_LEAST voxel sides, so that a close-up's colors blend between voxels instead of
# showing them as blocks.
COLOR_SPREAD = 0.6
COLOR_LEAST = 0.5
# Rays per side at silhouette pixels: 3 errs as 2 and traces longer; 1 makes the NVR+ err more on single-colored
# chairs (MC).
SUBPIXELS = 2
# A ray covers its pixel by how deep it goes into the part it meets: not at all when it only touches
# SURFACE_LEVEL, fully when within COVERAGE_PROBE voxels past the surface it gets COVERAGE_FULL of the
# way from there to the part's core (the least distance around it: 0 in a thick part, more in a thin
# one). This thins the hull's silhouettes towards the mesh's and keeps thin parts opaque face on.
CORE_SIZE = 5  # voxels: the neighbourhood a part's core is the least distance of
COVERAGE_FULL = 0.7
COVERAGE_PROBE = 4.0
# A ray through a thin panel seen at a slant does not go deep either, so the coverage above leaves specks of floor
# showing through solid panels (about 9 % of one test chair's interior pixels). A group of partly covered pixels
# that no empty pixel touches, at most SPECK_PIXELS at 256^2 (in proportion to the image's area), is covered fully;
# openings a ray passes through keep their empty pixels and stay open.
SPECK_PIXELS = 40
# The floor's glossy coat mirrors the object, in the shader's own image: the object mirrored in the floor is traced
# where the floor shows, at 1/REFLECTION_SUBSAMPLING of the image's side, lit like the object, blurred by REFLECTION_BLUR
# of its pixels (the coat's roughness), and replaces the sky the coat mirrored there by the coat's Fresnel reflectance
# times REFLECTION_SCALE. These values erred least of those tried; a finer trace did no better. A network's input
# leaves it out: the shipped NVR+ learned a reflection from its data and errs more when given it (DC).
REFLECTION_SUBSAMPLING = 4
REFLECTION_BLUR = 1.0
REFLECTION_SCALE = 0.5
CANDIDATE_SLACK = 0.01  # voxels of gap a cell may have beyond a hit's and still mark its pixels as ray candidates
CANDIDATE_DEPTH = 0.25  # voxels of gap inside the surface a cell's points must reach to count (a ray stops within 0.1)
CELL_RUN = 4  # cells along the last axis whose pixels are marked as one box (more: fewer boxes, more pixels traced)
COARSE_CELLS = 4  # cells per side of the blocks marked as one box for the floor's reflection


@dataclass(frozen=True)
class ShaderQuality:
    """How finely the shader samples its dearest terms: rays per side at silhouette pixels (anti-aliasing), points
    per side of the square light (shadow maps, soft shadows), rings of the normals' disc (NORMAL_RINGS; 0: the
    smoothed field's gradient alone) and the spread of a point's color over its pixel's footprint (COLOR_SPREAD
    pixel sides; 0: its voxel's color), and whether the sky light is occluded (`ambient_occlusion`: the object's
    points probed along their normals, the floor's straight up; False: every point sees the whole sky, which changed
    the fast NVR+'s error by under 2 %). FULL_QUALITY is what the networks were trained on; FAST_QUALITY takes about a
    fifth off an NVR+ frame after an object move and errs more (docs/results.md, "Speed")."""

    silhouette_rays: int = SUBPIXELS
    light_points: int = LIGHT_POINTS
    normal_rings: int = NORMAL_RINGS
    color_spread: float = COLOR_SPREAD
    ambient_occlusion: bool = True

    def __post_init__(self) -> None:
        if not (1 <= self.silhouette_rays <= 8 and 1 <= self.light_points <= 8):
            raise InputError(f"shader quality: silhouette rays and light points per side must be in [1, 8], got "
                             f"{self.silhouette_rays} and {self.light_points}")
        if not (0 <= self.normal_rings <= 8 and 0.0 <= self.color_spread <= 4.0):
            raise InputError(f"shader quality: normal rings must be in [0, 8] and the color spread in [0, 4] pixel "
                             f"sides, got {self.normal_rings} and {self.color_spread}")


FULL_QUALITY = ShaderQuality()
FAST_QUALITY = ShaderQuality(silhouette_rays=1, light_points=2, normal_rings=0, color_spread=0.0,
                             ambient_occlusion=False)


QUALITIES = {"full": FULL_QUALITY, "fast": FAST_QUALITY}  # by the name the command line and the editor use


def quality_named(name: str) -> ShaderQuality:
    """The ShaderQuality a name of QUALITIES stands for; an InputError for any other name."""
    if name not in QUALITIES:
        raise InputError(f"unknown shader quality {name!r} (choose from {', '.join(QUALITIES)})")
    return QUALITIES[name]
