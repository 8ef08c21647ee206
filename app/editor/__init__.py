"""The NVR Studio editor: a voxel viewport, editing tools and the live neural render side by side.

Importing imgui_bundle first points the glfw package at the glfw library imgui_bundle's native
backends are linked against, so every module here can `import glfw` and share one glfw state.
"""

import imgui_bundle  # noqa: F401
