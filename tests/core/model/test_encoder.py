"""ResNet-10-v1 down-sampling network and the up-sampling decoder: shapes, channels, sizes."""
import pytest
import torch

from cerberus_core.model.encoder import BasicBlock, ResNet10, UpDecoder, resnet10


def test_resnet10_pyramid_shapes_and_paper_channels():
    net = resnet10(3)
    f = net(torch.rand(2, 3, 64, 64))
    assert net.channels == (64, 128, 256, 512)
    assert f.c1.shape == (2, 64, 16, 16)
    assert f.c2.shape == (2, 128, 8, 8)
    assert f.c3.shape == (2, 256, 4, 4)
    assert f.c4.shape == (2, 512, 2, 2)


def test_resnet10_is_ten_layers_of_v1_basic_blocks():
    net = resnet10(3)
    convs = [m for name, m in net.named_modules() if isinstance(m, torch.nn.Conv2d) and "shortcut" not in name]
    assert len(convs) == 9  # stem + 4 blocks x 2 convolutions; with the final linear map: 10 layers
    blocks = [m for m in net.modules() if isinstance(m, BasicBlock)]
    assert len(blocks) == 4
    # v1: the block's output goes through ReLU after the residual addition (non-negative output)
    x = torch.randn(1, 64, 8, 8)
    assert (blocks[0](x) >= 0).all()


def test_resnet10_width_and_input_channels():
    net = resnet10(in_channels=1, width=16)
    f = net(torch.rand(1, 1, 96, 64))
    assert f.c4.shape == (1, 128, 3, 2)
    assert net.out_channels == 128


def test_resnet10_rejects_bad_inputs():
    with pytest.raises(ValueError, match="at least 32"):
        ResNet10()(torch.rand(1, 3, 16, 16))
    with pytest.raises(ValueError, match=r"\(B, C, H, W\)"):
        ResNet10()(torch.rand(3, 64, 64))


@pytest.mark.parametrize("size", [(64, 64), (80, 48), (70, 70)])
def test_decoder_returns_stride4_features(size):
    net = ResNet10(width=8)
    dec = UpDecoder(net.channels)
    f = net(torch.rand(2, 3, *size))
    out = dec(f)
    assert out.shape == (2, 8, *f.c1.shape[-2:])


def test_decoder_uses_skip_connections():
    """Changing the stage-1 features changes the decoder output directly (the skip connection)."""
    net = ResNet10(width=8).eval()
    dec = UpDecoder(net.channels).eval()
    f = net(torch.rand(1, 3, 64, 64))
    base = dec(f)
    f.c1 = f.c1 + 1.0
    assert torch.allclose(dec(f) - base, torch.ones_like(base))
