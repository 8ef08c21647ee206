"""The voxel shader: a physically based image of the voxel scene (see shader.py)."""

from renderer.shading.shader import (
    BUFFER_CHANNELS,
    ObjectGeometry,
    ShadedImage,
    VisibleSurface,
    moved,
    network_buffers,
    object_geometry,
    repaint_surface,
    shade,
    shade_grid,
    shade_scene,
    visible_surface,
)

__all__ = ["BUFFER_CHANNELS", "ObjectGeometry", "ShadedImage", "VisibleSurface", "moved", "object_geometry", "repaint_surface", "shade", "network_buffers", "shade_grid", "shade_scene",
           "visible_surface"]
