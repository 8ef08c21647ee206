"""The physically based reference renderer on Mitsuba 3: the scene (mitsuba_object.py), the variant
that runs it (mitsuba_variant.py), path tracing and denoising (path_tracer.py)."""

from renderer.pathtrace.path_tracer import PathTracer, PathtraceResult, render_pathtraced

__all__ = ["PathTracer", "PathtraceResult", "render_pathtraced"]
