"""The voxel shader: a physically based image of the voxel scene (shader.py gives the overview)."""

from renderer.shading.buffers import BUFFER_CHANNELS, network_buffers
from renderer.shading.geometry import ObjectGeometry, object_geometry, placed
from renderer.shading.lighting import ShadedImage, shade
from renderer.shading.quality import FAST_QUALITY, FULL_QUALITY, QUALITIES, ShaderQuality, quality_named
from renderer.shading.shader import shade_objects, shade_scene, shadows_of_others
from renderer.shading.surface import FloorReflection, VisibleSurface, floor_reflection, repaint_surface, visible_surface

__all__ = ["BUFFER_CHANNELS", "FAST_QUALITY", "FULL_QUALITY", "QUALITIES", "FloorReflection", "ObjectGeometry",
           "ShadedImage", "ShaderQuality", "VisibleSurface", "floor_reflection", "network_buffers", "object_geometry",
           "placed", "quality_named", "repaint_surface", "shade", "shade_objects", "shade_scene", "shadows_of_others", "visible_surface"]
