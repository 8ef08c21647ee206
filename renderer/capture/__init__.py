"""Appearance capture from a photo: the photo's pose (camera file, manual or found), the object's
silhouette in it, and the voxel colors taken from it. See renderer/capture/capture.py for the whole path.
"""
