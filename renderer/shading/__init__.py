"""The voxel shader: a physically based image of the voxel scene (see shader.py)."""

from renderer.shading.shader import (
    ObjectGeometry,
    ShadedImage,
    VisibleSurface,
    object_geometry,
    shade,
    shade_grid,
    shade_scene,
    visible_surface,
)

__all__ = ["ObjectGeometry", "ShadedImage", "VisibleSurface", "object_geometry", "shade", "shade_grid", "shade_scene",
           "visible_surface"]
