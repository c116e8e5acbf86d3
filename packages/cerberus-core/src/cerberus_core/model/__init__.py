"""The Cerberus model: ResNet-10-v1 encoder, up-sampling decoder, shape/rotation/translation heads.

>>> import torch
>>> from cerberus_core import Camera
>>> from cerberus_core.model import Cerberus, ModelConfig
>>> model = Cerberus(ModelConfig(depth_offset=2.2)).eval()
>>> images = torch.rand(2, 3, 64, 64)                      # (B, 3, H, W) float32 in [0, 1]
>>> camera = Camera.look_at([0.0, 90.0], 15.0, 2.2)        # the B cameras that took them
>>> parts = model.reconstruct(images, camera)
>>> tuple(parts.posed().shape)                             # (B, 9 parts, 162 vertices, 3) world coordinates
(2, 9, 162, 3)
"""
from cerberus_core.model.cerberus import (
    Cerberus,
    ModelConfig,
    Predictions,
)
from cerberus_core.model.encoder import FeaturePyramid, ResNet10, UpDecoder, resnet10
from cerberus_core.model.heads import KeypointMaps, expectation, unproject_expectation

__all__ = [
    "Cerberus",
    "FeaturePyramid",
    "KeypointMaps",
    "ModelConfig",
    "Predictions",
    "ResNet10",
    "UpDecoder",
    "expectation",
    "resnet10",
    "unproject_expectation",
]
