"""Evaluation: the metrics of the paper's table 1 (metrics.py: MSE, DSSIM, perceptual) and `nvr eval` (evaluate.py)."""
