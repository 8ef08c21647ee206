"""Training: data sets as tensors (data.py), the loss of eq. 2 (loss.py), the resumable loop (train.py), distillation
(distill.py), and their configurations without torch (config.py), which the command line reads."""
