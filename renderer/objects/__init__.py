"""Procedural furniture with part labels and appearances: the project's stand-in for ShapeNet (paper 4.1).

generate_object(category, seed) builds one watertight, part-labelled object in the object box;
apply_appearance(obj, setting, seed, split) colors it (single, default or textured) and draws
a floor color; split_seeds(split, count) gives the disjoint train and test object seeds.
"""

from renderer.objects.appearance import SETTINGS, apply_appearance
from renderer.objects.assembly import LabeledMesh
from renderer.objects.generate import CATEGORIES, SPLITS, generate_object, split_seed, split_seeds

__all__ = ["CATEGORIES", "SETTINGS", "SPLITS", "LabeledMesh", "apply_appearance", "generate_object", "split_seed", "split_seeds"]
