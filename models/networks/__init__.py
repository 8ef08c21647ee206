"""NVR and NVR+ (paper 3.3, 3.4): configurations (config.py, without torch), layers, the networks (nvr.py), safetensors
weights files (checkpoint.py), inference copies (inference.py) and the shipped weights' paths (shipped.py)."""
