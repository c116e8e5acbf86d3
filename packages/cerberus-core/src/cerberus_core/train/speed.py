"""Speed switches of training (the ``speed:`` config section), all off by default.

They change how the network runs, not what it computes, up to rounding: ``autocast`` runs the
convolutional trunk (the ResNet encoder and the up-sampling decoder) in bfloat16 while the heads,
the poses, the renderer and every loss stay in float32; ``channels_last`` stores the trunk's
activations and weights NHWC (faster convolutions on CPUs with oneDNN, and what bfloat16 kernels
prefer); ``compile`` runs the trunk through ``torch.compile`` (a one-off compilation of tens of
seconds; needs a C++ compiler on the CPU); ``smoothness_once`` computes the smoothness loss once per
quadruplet (applied by the objective, not the model). Checkpoints are unchanged by every switch (the same state
dict keys and float32 weights), so a run can be resumed, evaluated or exported with any setting; a
resumed run is exact when its switches match the interrupted run's.

``benchmarks/bench_train.py --switches`` times each switch side by side.
"""
from __future__ import annotations

from dataclasses import dataclass

import torch

from cerberus_core.model.cerberus import Cerberus

AUTOCAST_DTYPES = {"bf16": torch.bfloat16}
"""Accepted values of ``speed.autocast`` (besides ``null``)."""


@dataclass
class SpeedConfig:
    """Attributes:
        autocast: ``bf16``: run the encoder and decoder under ``torch.autocast(dtype=bfloat16)``
            (heads, geometry, rendering and losses stay float32); ``null``: off.
        channels_last: convert the encoder and decoder to the channels-last memory format.
        compile: ``torch.compile`` the encoder and decoder (``nn.Module.compile``, in place: the
            state dict keeps its keys).
        smoothness_once: with pose consistency, compute the smoothness loss once per quadruplet
            instead of once per image (the four images decode one mixed shape latent, so their
            meshes are equal): a quarter of its cost, the same loss value, gradients equal up to
            float rounding (:func:`cerberus_core.train.objective.smoothness_term`).
    """

    autocast: str | None = None
    channels_last: bool = False
    compile: bool = False
    smoothness_once: bool = False

    def validate(self) -> None:
        if self.autocast is not None and self.autocast not in AUTOCAST_DTYPES:
            raise ValueError(f"speed.autocast must be null or one of {sorted(AUTOCAST_DTYPES)}, got {self.autocast!r}")


def apply_speed(model: Cerberus, speed: SpeedConfig) -> Cerberus:
    """Switch ``model``'s trunk to the settings of ``speed`` (in place; returns ``model``).

    Call it after moving the model to its device. Parameters keep their identity (an optimiser
    built before or after sees the same tensors) and the state dict keeps its keys and dtypes.
    """
    speed.validate()
    trunk = (model.encoder, model.decoder)
    if speed.channels_last:
        for module in trunk:
            module.to(memory_format=torch.channels_last)
    model.cnn_autocast = AUTOCAST_DTYPES[speed.autocast] if speed.autocast is not None else None
    if speed.compile:
        for module in trunk:
            module.compile()
    return model


def release_speed(model: Cerberus) -> Cerberus:
    """Turn autocast off again (training is over: evaluation should see the float32 network).
    The memory format and compilation stay; neither changes results beyond rounding."""
    model.cnn_autocast = None
    return model
