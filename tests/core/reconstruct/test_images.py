"""Input images for `cerberus reconstruct`: converted with a note, or refused naming the file."""
from __future__ import annotations

import numpy as np
import pytest
import torch
from PIL import Image

from cerberus_core.errors import ImageInputError
from cerberus_core.reconstruct.images import ImageInputWarning, load_image, load_images

S = 32


def _save(path, array, mode=None):
    Image.fromarray(array, mode=mode).save(path)
    return path


def test_matching_rgb_image_passes_unchanged(tmp_path):
    arr = np.random.default_rng(0).integers(0, 256, (S, S, 3), dtype=np.uint8)
    li = load_image(_save(tmp_path / "ok.png", arr), S)
    assert li.notes == [] and li.image.shape == (3, S, S) and li.image.dtype == torch.float32
    np.testing.assert_allclose(li.image.permute(1, 2, 0).numpy(), arr / 255.0, atol=1e-6)


def test_rgba_is_composited_over_background(tmp_path):
    arr = np.zeros((S, S, 4), dtype=np.uint8)
    arr[..., 0] = 255  # red ...
    arr[:, : S // 2, 3] = 255  # ... opaque on the left half, transparent on the right
    with pytest.warns(ImageInputWarning, match="alpha"):
        li = load_image(_save(tmp_path / "rgba.png", arr, "RGBA"), S, background=(0.0, 0.5, 1.0))
    img = li.image.permute(1, 2, 0).numpy()
    np.testing.assert_allclose(img[0, 0], [1, 0, 0])
    np.testing.assert_allclose(img[0, -1], [0, 0.5, 1.0])


def test_wrong_size_and_aspect_are_cropped_and_resized(tmp_path):
    arr = np.full((60, 100, 3), 200, dtype=np.uint8)
    arr[:, :20] = 0  # a dark band that the centre crop removes
    with pytest.warns(ImageInputWarning) as rec:
        li = load_image(_save(tmp_path / "wide.png", arr), S)
    msgs = " ".join(str(w.message) for w in rec)
    assert "centre-cropped from 100x60 to 60x60" in msgs and f"resized from 60x60 to {S}x{S}" in msgs
    assert li.image.shape == (3, S, S) and li.original_size == (100, 60)
    assert li.image.min() > 0.7  # the band is gone, no ringing below 0


def test_grayscale_and_16_bit_are_converted(tmp_path):
    grey = np.tile(np.linspace(0, 255, S, dtype=np.uint8), (S, 1))
    with pytest.warns(ImageInputWarning, match="grayscale"):
        li = load_image(_save(tmp_path / "grey.png", grey, "L"), S)
    assert torch.equal(li.image[0], li.image[2])
    deep = (np.tile(np.linspace(0, 65535, S), (S, 1))).astype(np.uint16)
    Image.fromarray(deep).save(tmp_path / "deep.png")
    with pytest.warns(ImageInputWarning, match="16-bit"):
        li16 = load_image(tmp_path / "deep.png", S)
    np.testing.assert_allclose(li16.image[0, 0].numpy(), deep[0] / 65535.0, atol=1e-6)


def test_unreadable_missing_and_float_images_are_refused_by_name(tmp_path):
    bad = tmp_path / "notes.png"
    bad.write_text("this is not an image")
    with pytest.raises(ImageInputError, match="notes.png: cannot be read as an image"):
        load_image(bad, S)
    with pytest.raises(ImageInputError, match="missing.png: no such file"):
        load_image(tmp_path / "missing.png", S)
    Image.fromarray(np.zeros((S, S), np.float32), mode="F").save(tmp_path / "float.tiff")
    with pytest.raises(ImageInputError, match="float.tiff: 32-bit float"):
        load_image(tmp_path / "float.tiff", S)
    with pytest.raises(ImageInputError, match="no input images"):
        load_images([], S)


def test_load_images_stacks(tmp_path):
    a = _save(tmp_path / "a.png", np.zeros((S, S, 3), np.uint8))
    b = _save(tmp_path / "b.png", np.full((S, S, 3), 255, np.uint8))
    batch, records = load_images([a, b], S, warn=False)
    assert batch.shape == (2, 3, S, S) and [r.path.name for r in records] == ["a.png", "b.png"]


def test_a_large_file_resized_to_the_model_is_one_note_in_the_file_s_pixels(tmp_path):
    """Issue 34: a file reduced on reading (box filter, while 8-bit) and then resized gave two warnings for its
    one resize ("downscaled 4x ... from 512x512" and "resized from 128x128 to 32x32")."""
    with pytest.warns(ImageInputWarning) as rec:
        li = load_image(_save(tmp_path / "big.png", np.full((4 * S + 8, 8 * S, 3), 90, np.uint8)), S)
    msgs = [str(w.message) for w in rec]
    assert msgs == [f"{tmp_path / 'big.png'}: centre-cropped from {8 * S}x{4 * S + 8} to {4 * S + 8}x{4 * S + 8}",
                    f"{tmp_path / 'big.png'}: resized from {4 * S + 8}x{4 * S + 8} to {S}x{S}"], msgs
    assert li.image.shape == (3, S, S) and li.original_size == (8 * S, 4 * S + 8)


def test_an_image_over_the_pixel_limit_is_said_once(tmp_path, monkeypatch):
    """Issue 34 campaign: the bound's own ImageInputError (a ValueError) was caught and wrapped again as "cannot be
    read as an image (ImageInputError: ...)", naming the file twice."""
    import cerberus_core.reconstruct.images as images

    monkeypatch.setattr(images, "MAX_INPUT_PIXELS", 100)
    Image.fromarray(np.zeros((20, 20, 3), np.uint8)).save(tmp_path / "big.png")
    with pytest.raises(ImageInputError) as caught:
        load_image(tmp_path / "big.png", 16)
    message = str(caught.value)
    assert "20x20 pixels is too large (the limit is 100 pixels)" in message
    assert "cannot be read" not in message and message.count("big.png") == 1
