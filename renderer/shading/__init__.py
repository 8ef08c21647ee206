"""The voxel shader: a physically based image of the voxel scene (see shader.py)."""

from renderer.shading.shader import (
    BUFFER_CHANNELS,
    FAST_QUALITY,
    FULL_QUALITY,
    QUALITIES,
    FloorReflection,
    ObjectGeometry,
    ShadedImage,
    ShaderQuality,
    VisibleSurface,
    floor_reflection,
    network_buffers,
    object_geometry,
    placed,
    quality_named,
    repaint_surface,
    shade,
    shade_scene,
    visible_surface,
)

__all__ = ["BUFFER_CHANNELS", "FAST_QUALITY", "FULL_QUALITY", "QUALITIES", "FloorReflection", "ObjectGeometry", "ShadedImage",
           "ShaderQuality", "VisibleSurface", "floor_reflection", "network_buffers", "object_geometry", "placed", "quality_named", "repaint_surface", "shade", "shade_scene", "visible_surface"]
