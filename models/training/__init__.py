"""Training: data sets as tensors, the loss of eq. 2 (L1 + perceptual), the loop with resumable runs."""

from models.training.data import VoxelRenderSet
from models.training.loss import RenderLoss
from models.training.train import TrainConfig, train

__all__ = ["RenderLoss", "TrainConfig", "VoxelRenderSet", "train"]
