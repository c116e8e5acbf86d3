"""The image backbone: a ResNet-10-v1 down-sampling network and the up-sampling decoder.

ResNet-10-v1 is the original (post-activation, "v1") residual network of He et al. with one basic
block per stage: a 7x7/2 convolution and a 3x3/2 max-pool stem, then four stages of one
:class:`BasicBlock` each with ``(64, 128, 256, 512)`` channels (times ``width / 64``) at strides
``(4, 8, 16, 32)`` relative to the input. Its forward returns the feature pyramid, so the decoder
can take skip connections from it.

The up-sampling network (:class:`UpDecoder`) has three stride-2 transposed convolutions; after each
one (batch norm, ReLU) the feature map of the down-sampling stage of the same resolution is added
(skip connection): stride 32 → 16 (+ stage 3) → 8 (+ stage 2) → 4 (+ stage 1). The per-part heads
(:mod:`cerberus_core.model.heads`) map that stride-4 feature map linearly (1x1 convolution) to
logits and depths and upsample them bilinearly to the input resolution, so probability maps and
depth maps are defined on the input pixel grid as in equation 1 of the paper. (The paper's three
transposed convolutions cannot undo the five halvings of a ResNet on their own; the last factor of
4 is this bilinear upsampling of the linear heads.)
"""
from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import nn

from cerberus_core.errors import ConfigError, ShapeError
from cerberus_core.shapes import check_shapes

Tensor = torch.Tensor


class BasicBlock(nn.Module):
    """ResNet v1 basic block: ``relu(bn(conv3x3(relu(bn(conv3x3(x))))) + shortcut(x))``.

    Args:
        cin, cout: input and output channels.
        stride: stride of the first convolution (and of the 1x1 projection shortcut).
    """

    def __init__(self, cin: int, cout: int, stride: int = 1) -> None:
        super().__init__()
        self.conv1 = nn.Conv2d(cin, cout, 3, stride, 1, bias=False)
        self.bn1 = nn.BatchNorm2d(cout)
        self.conv2 = nn.Conv2d(cout, cout, 3, 1, 1, bias=False)
        self.bn2 = nn.BatchNorm2d(cout)
        self.shortcut: nn.Module = nn.Identity()
        if stride != 1 or cin != cout:
            self.shortcut = nn.Sequential(nn.Conv2d(cin, cout, 1, stride, bias=False), nn.BatchNorm2d(cout))

    def forward(self, x: Tensor) -> Tensor:
        y = torch.relu(self.bn1(self.conv1(x)))
        y = self.bn2(self.conv2(y))
        return torch.relu(y + self.shortcut(x))


@dataclass
class FeaturePyramid:
    """Outputs of the down-sampling network for an input of size ``H x W``.

    Attributes:
        c1: ``(B, C, H/4, W/4)`` stage-1 features (``C = width``).
        c2: ``(B, 2C, H/8, W/8)``.
        c3: ``(B, 4C, H/16, W/16)``.
        c4: ``(B, 8C, H/32, W/32)`` the lowest resolution; its global average is the object latent.
    """

    c1: Tensor
    c2: Tensor
    c3: Tensor
    c4: Tensor


class ResNet10(nn.Module):
    """ResNet-10-v1 down-sampling network returning a :class:`FeaturePyramid`.

    Args:
        in_channels: image channels (3 for RGB).
        width: channels of the first stage; the stages have ``width * (1, 2, 4, 8)`` channels
            (64 gives the paper's 64, 128, 256, 512).

    Inputs should be at least 32 pixels on each side (the last stage is at stride 32).
    """

    def __init__(self, in_channels: int = 3, width: int = 64) -> None:
        super().__init__()
        if in_channels < 1 or width < 1:
            raise ConfigError(f"ResNet10 needs positive in_channels and width, got {in_channels}, {width}; pass "
                              "`in_channels` >= 1 and `width` >= 1", key="width", value=width)
        self.channels = (width, 2 * width, 4 * width, 8 * width)
        self.stem = nn.Sequential(
            nn.Conv2d(in_channels, width, 7, 2, 3, bias=False),
            nn.BatchNorm2d(width),
            nn.ReLU(inplace=True),
            nn.MaxPool2d(3, 2, 1),
        )
        c = self.channels
        self.layer1 = BasicBlock(c[0], c[0], 1)
        self.layer2 = BasicBlock(c[0], c[1], 2)
        self.layer3 = BasicBlock(c[1], c[2], 2)
        self.layer4 = BasicBlock(c[2], c[3], 2)
        for m in self.modules():
            if isinstance(m, nn.Conv2d):
                nn.init.kaiming_normal_(m.weight, mode="fan_out", nonlinearity="relu")

    @property
    def out_channels(self) -> int:
        """Channels of the lowest-resolution feature map (the object latent size)."""
        return self.channels[3]

    def forward(self, images: Tensor) -> FeaturePyramid:
        """``(B, in_channels, H, W)`` → :class:`FeaturePyramid`."""
        check_shapes("ResNet10", images=(images, "B C H W"))
        if min(images.shape[-2:]) < 32:
            raise ShapeError(f"ResNet10 needs images of at least 32x32 pixels, got {tuple(images.shape[-2:])}; "
                             "resize the images to 32x32 or more")
        c1 = self.layer1(self.stem(images))
        c2 = self.layer2(c1)
        c3 = self.layer3(c2)
        c4 = self.layer4(c3)
        return FeaturePyramid(c1, c2, c3, c4)


def resnet10(in_channels: int = 3, width: int = 64) -> ResNet10:
    """The paper's down-sampling network, ResNet-10-v1 (channels 64, 128, 256, 512 by default).

    ``resnet10(3)(images)`` with ``images`` ``(B, 3, H, W)`` returns a :class:`FeaturePyramid` with
    feature maps at strides 4, 8, 16 and 32 (``.c1`` ... ``.c4``).
    """
    return ResNet10(in_channels, width)


class UpBlock(nn.Module):
    """One decoder step: stride-2 transposed convolution, batch norm, ReLU, plus the skip features."""

    def __init__(self, cin: int, cout: int) -> None:
        super().__init__()
        self.deconv = nn.ConvTranspose2d(cin, cout, 4, 2, 1, bias=False)
        self.bn = nn.BatchNorm2d(cout)

    def forward(self, x: Tensor, skip: Tensor) -> Tensor:
        y = torch.relu(self.bn(self.deconv(x)))
        if y.shape[-2:] != skip.shape[-2:]:  # odd input sizes: crop/pad to the skip's grid
            y = nn.functional.interpolate(y, size=skip.shape[-2:], mode="bilinear", align_corners=False)
        return y + skip


class UpDecoder(nn.Module):
    """Up-sampling network: three transposed convolutions with additive skip connections.

    Args:
        channels: the encoder's stage channels ``(C1, C2, C3, C4)``.

    ``forward(pyramid)`` returns ``(B, C1, H/4, W/4)`` features.
    """

    def __init__(self, channels: tuple[int, int, int, int]) -> None:
        super().__init__()
        c1, c2, c3, c4 = channels
        self.up3 = UpBlock(c4, c3)
        self.up2 = UpBlock(c3, c2)
        self.up1 = UpBlock(c2, c1)
        self.out_channels = c1

    def forward(self, f: FeaturePyramid) -> Tensor:
        x = self.up3(f.c4, f.c3)
        x = self.up2(x, f.c2)
        return self.up1(x, f.c1)
