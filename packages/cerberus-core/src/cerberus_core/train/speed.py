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
from typing import Literal

import torch

from cerberus_core.devices import native_bf16
from cerberus_core.fields import Checked
from cerberus_core.model.cerberus import Cerberus

AUTOCAST_DTYPES = {"bf16": torch.bfloat16}
"""Accepted values of ``speed.autocast`` (besides ``null`` and ``auto``)."""


def resolve_autocast(value: str | None, device: torch.device | str) -> tuple[str | None, str]:
    """``speed.autocast`` as it will run on ``device``: ``auto`` becomes ``bf16`` where the device
    computes bfloat16 natively (:func:`cerberus_core.devices.native_bf16`: AVX512_BF16 or AMX on an
    x86 CPU, BF16 on Arm, a bfloat16 GPU) and ``null`` elsewhere (an AVX2-only CPU emulates bfloat16
    products and runs them slower than float32). Other values are returned as they are.

    Returns:
        ``(value, reason)``: the resolved value and a line that says why.
    """
    if value != "auto":
        return value, "set in the config"
    native, why = native_bf16(str(device))
    return ("bf16" if native else None), f"auto: {why}"


@dataclass
class SpeedConfig(Checked):
    """Attributes:
        autocast: ``bf16``: run the encoder and decoder under ``torch.autocast(dtype=bfloat16)``
            (heads, geometry, rendering and losses stay float32); ``null``: off; ``auto``: ``bf16``
            where the device computes bfloat16 natively, else off (:func:`resolve_autocast`; the
            trainer saves the resolved value in the run's config and says which).
        channels_last: convert the encoder and decoder to the channels-last memory format.
        compile: ``torch.compile`` the encoder and decoder (``nn.Module.compile``, in place: the
            state dict keeps its keys).
        smoothness_once: with pose consistency, compute the smoothness loss once per quadruplet
            instead of once per image (the four images decode one mixed shape latent, so their
            meshes are equal): a quarter of its cost, the same loss value, gradients equal up to
            float rounding (:func:`cerberus_core.train.objective.smoothness_term`).
    """

    SECTION = "speed"

    autocast: Literal["auto", "bf16"] | None = None
    channels_last: bool = False
    compile: bool = False
    smoothness_once: bool = False


def apply_speed(model: Cerberus, speed: SpeedConfig) -> Cerberus:
    """Switch ``model``'s trunk to the settings of ``speed`` (in place; returns ``model``).

    Call it after moving the model to its device. Parameters keep their identity (an optimiser
    built before or after sees the same tensors) and the state dict keeps its keys and dtypes.
    """
    speed.check()
    autocast, _ = resolve_autocast(speed.autocast, next(model.parameters()).device)
    trunk = (model.encoder, model.decoder)
    if speed.channels_last:
        for module in trunk:
            module.to(memory_format=torch.channels_last)
    model.cnn_autocast = AUTOCAST_DTYPES[autocast] if autocast is not None else None
    if speed.compile:
        for module in trunk:
            module.compile()
    return model


def release_speed(model: Cerberus) -> Cerberus:
    """Turn autocast off again (training is over: evaluation should see the float32 network).
    The memory format and compilation stay; neither changes results beyond rounding."""
    model.cnn_autocast = None
    return model
