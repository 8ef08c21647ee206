"""Scenes, voxels, shading and images."""

import warnings

# An older TBB loaded first by another package (open3d bundles one) makes numba fall back to OpenMP, which is what it
# would use anyway; its warning says nothing a user can act on. Set here, before any of the package's numba kernels
# (sRGB encoding, the shader) first runs.
warnings.filterwarnings("ignore", message="The TBB threading layer requires TBB version")
