"""Evaluation: the metrics of the paper's table 1 (MSE, DSSIM, perceptual) and `nvr eval`."""

from models.evaluation.evaluate import evaluate, resolution_study
from models.evaluation.metrics import ImageMetrics, dssim, mse_255

__all__ = ["ImageMetrics", "dssim", "evaluate", "mse_255", "resolution_study"]
