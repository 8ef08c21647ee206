"""NVR and NVR+ (paper 3.3, 3.4): configurations, layers, safetensors weights files, inference copies."""

from models.networks.checkpoint import load_model, save_model
from models.networks.config import CompactConfig, NVRConfig, PaperConfig
from models.networks.inference import prepare_for_inference
from models.networks.nvr import NVR, NVRPlus, build_model, light_to_network, reads_floor_light

__all__ = ["NVR", "CompactConfig", "NVRConfig", "NVRPlus", "PaperConfig", "build_model", "light_to_network",
           "load_model", "prepare_for_inference", "reads_floor_light", "save_model"]
