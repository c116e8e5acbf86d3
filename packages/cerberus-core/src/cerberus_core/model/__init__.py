"""The Cerberus model: ResNet-10-v1 encoder, up-sampling decoder, shape/rotation/translation heads.

>>> from cerberus_core.model import Cerberus, ModelConfig
>>> model = Cerberus(ModelConfig(depth_offset=2.2))
>>> parts = model.reconstruct(images, camera)   # images (B, 3, H, W), camera: B cameras
>>> parts.posed().shape                          # (B, 9, 162, 3) world coordinates
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
