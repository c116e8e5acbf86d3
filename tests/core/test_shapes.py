"""The one shape check (cerberus_core.shapes.check_shapes, like kornia's KORNIA_CHECK_SHAPE)."""
import pytest
import torch

from cerberus_core.parts import PartSet
from cerberus_core.shapes import check_shapes


def test_names_bind_sizes_across_tensors_and_numbers_must_match():
    sizes = check_shapes("f", a=(torch.zeros(2, 4, 7), "B 4 S"), b=(torch.zeros(2, 7), "B S"))
    assert sizes == {"B": 2, "S": 7}
    with pytest.raises(ValueError, match=r"^f: b must be \(B, S\), got \(2, 6\) \(with B=2, S=7\)$"):
        check_shapes("f", a=(torch.zeros(2, 4, 7), "B 4 S"), b=(torch.zeros(2, 6), "B S"))
    with pytest.raises(ValueError, match=r"f: a must be \(B, 4, S\), got \(2, 3, 7\)"):
        check_shapes("f", a=(torch.zeros(2, 3, 7), "B 4 S"))
    with pytest.raises(ValueError, match=r"got \(2, 4\)"):
        check_shapes("f", a=(torch.zeros(2, 4), "B 4 S"))


def test_leading_dimensions_and_wildcards():
    assert check_shapes("g", x=(torch.zeros(5, 3, 8, 8), "... 3 H W"), y=(torch.zeros(5, 3, 8, 8), "... 3 H W")) == \
        {"H": 8, "W": 8}
    assert check_shapes("g", x=(torch.zeros(3, 8, 8), "... 3 H W")) == {"H": 8, "W": 8}
    with pytest.raises(ValueError, match="y must be"):  # the leading dimensions differ
        check_shapes("g", x=(torch.zeros(5, 3, 8, 8), "... 3 H W"), y=(torch.zeros(4, 3, 8, 8), "... 3 H W"))
    assert check_shapes("g", x=(torch.zeros(2, 9), "_ N")) == {"N": 9}


def test_partset_and_losses_name_the_tensor_that_does_not_fit():
    from cerberus_core.losses import mix_shape_latents, translation_loss

    with pytest.raises(ValueError, match=r"PartSet: rotations must be \(B, P, 3, 3\), got \(1, 2, 3, 3\)"):
        PartSet(torch.zeros(1, 3, 5, 3), torch.zeros(2, 3, dtype=torch.int64), torch.zeros(1, 2, 3, 3),
                torch.zeros(1, 3, 3))
    with pytest.raises(ValueError, match=r"mix_shape_latents: latents must be \(B, 4, S\)"):
        mix_shape_latents(torch.zeros(2, 3, 8))
    with pytest.raises(ValueError, match=r"translation_loss: translations must be \(B, 4, N, 3\)"):
        translation_loss(torch.zeros(2, 4, 9))


def test_an_argument_that_is_not_an_array_is_named():
    """Issue 34 campaign: ``render(ctx, vertices.tolist(), ...)`` was an AttributeError ('list' has no 'shape')."""
    from cerberus_core.errors import DeviceError, InputTypeError

    with pytest.raises(InputTypeError, match=r"render: vertices is a list, not a tensor of shape \(B, V, 3\)"):
        check_shapes("render", vertices=([[0.0, 0.0, 0.0]], "B V 3"))
    with pytest.raises(DeviceError, match="vertices on the meta device, which holds no values"):
        check_shapes("render", vertices=(torch.zeros(1, 2, 3, device="meta"), "B V 3"))
