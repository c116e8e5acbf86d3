"""The automatic person mask (cerberus_core.photo_mask): the extra named when it is missing, the silhouette IoU and
the pictures written beside a masked reconstruction, and (with ``cerberus-core[photo]`` installed) the segmenter
itself, offline."""
from __future__ import annotations

import socket
import sys

import numpy as np
import pytest
from PIL import Image

from cerberus_core import Run
from cerberus_core.cli import main
from cerberus_core.datasets.dataset import Dataset
from cerberus_core.errors import MissingPackageError
from cerberus_core.eval.masks import mask_iou
from cerberus_core.photo_mask import (
    PHOTO_EXTRA,
    SILHOUETTE_THRESHOLD,
    overlap_picture,
    person_mask,
    require_segmenter,
    segmenter_available,
)

pytestmark = pytest.mark.usefixtures("one_thread")


@pytest.fixture
def without_extra(monkeypatch):
    """The photo extra absent, as on a clean clone: its module cannot be found or imported."""
    monkeypatch.setitem(sys.modules, "mediapipe", None)


@pytest.fixture(scope="module")
def body_png(tmp_path_factory):
    """A generated human test image as a PNG at 4x the model's size, and its exact mask (white on the body)."""
    root = tmp_path_factory.mktemp("photo")
    assert main(["data", "generate", "--dataset", "human", "--size", "tiny", "--set", "splits.train.pairs=1",
                 "--set", "image_size=256", "--out", str(root / "data"), "--quiet"]) == 0
    ds = Dataset.open(root / "data").views("test")
    image = ds[0]["images"].numpy().transpose(1, 2, 0)
    Image.fromarray((image * 255 + 0.5).astype(np.uint8)).save(root / "body.png")
    mask = np.abs(image - np.asarray(ds.scene.background)).max(-1) > 0.5 / 255
    Image.fromarray(mask.astype(np.uint8) * 255).save(root / "body_mask.png")
    return root / "body.png", root / "body_mask.png", image


def test_the_overlap_colours():
    a, b = np.zeros((4, 4)), np.zeros((4, 4))
    a[:2], b[1:3] = 1, 1
    pic = overlap_picture(a, b)
    assert tuple(pic[1, 0]) == (150, 150, 150) and tuple(pic[0, 0]) == (50, 90, 220)  # both / rendered only
    assert tuple(pic[2, 0]) == (220, 40, 40) and tuple(pic[3, 0]) == (255, 255, 255)  # mask only / neither


def test_without_the_extra_auto_names_it_in_one_line(without_extra, body_png, tmp_path, capsys):
    assert not segmenter_available()
    with pytest.raises(MissingPackageError, match=r"optional extra cerberus-core\[photo\].*give a mask file"):
        require_segmenter()
    with pytest.raises(MissingPackageError, match=r"cerberus-core\[photo\]"):
        person_mask(np.zeros((8, 8, 3)))
    with pytest.raises(MissingPackageError, match=r"cerberus-core\[photo\]"):
        Run.load("human").reconstruct_images([body_png[0]], tmp_path / "lib", masks="auto")
    assert main(["reconstruct", "--model", "human", str(body_png[0]), "--mask", "auto", "--out",
                 str(tmp_path / "cli")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and PHOTO_EXTRA in err and "pip install" in err
    assert not (tmp_path / "cli").exists() and not (tmp_path / "lib").exists()


def test_a_mask_file_named_auto_is_a_file(without_extra, body_png, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["reconstruct", "--model", "human", str(body_png[0]), "--mask", "./auto", "--out",
                 str(tmp_path / "cli")]) == 2
    err = capsys.readouterr().err
    assert PHOTO_EXTRA not in err and "auto" in err


def test_a_masked_reconstruction_writes_its_steps_and_silhouette_iou(body_png, tmp_path):
    """With a mask file (no extra needed): ``NAME_steps.png`` (photo, mask, framed input, parts, silhouettes) and
    the rendered silhouette's IoU against the framed mask, after the fit to the mask and before it (the network's);
    no ``NAME_mask.png``, which only an automatic mask writes. ``fit=0`` keeps the network's prediction."""
    image, mask, _ = body_png
    result = Run.load("human").reconstruct_images([image], tmp_path / "rec", masks=[mask], viewer_images=0)
    (iou,), (network,) = result.silhouette_ious, result.network_ious
    assert 0.5 < network <= 1.0  # the shipped model on a generated body covers most of it
    assert iou > network + 0.03 and result.fit_steps == 100  # the fit moves the outline onto the mask
    steps = Image.open(tmp_path / "rec" / "body_steps.png")
    assert steps.width > 4 * steps.height  # five panels side by side
    assert not (tmp_path / "rec" / "body_mask.png").exists()
    assert any(line.startswith("silhouette IoU of the reconstruction against the mask after fitting it to the mask "
                               f"for 100 steps: body {iou:.3f} (network {network:.3f})")
               for line in result.lines(viewer=False))
    unfitted = Run.load("human").reconstruct_images([image], tmp_path / "net", masks=[mask], viewer_images=0, fit=0)
    assert unfitted.silhouette_ious == unfitted.network_ious == [network] and unfitted.fit_steps == 0
    assert any(line == f"silhouette IoU of the reconstruction against the mask: body {network:.3f}"
               for line in unfitted.lines(viewer=False))


def test_reconstruct_fit_flag(body_png, tmp_path, capsys):
    image, mask, _ = body_png
    assert main(["reconstruct", "--model", "human", str(image), "--mask", str(mask), "--fit", "0",
                 "--viewer-images", "0", "--out", str(tmp_path / "cli")]) == 0
    assert "after fitting" not in capsys.readouterr().out
    assert main(["reconstruct", "--model", "human", str(image), "--mask", str(mask), "--fit", "-1",
                 "--out", str(tmp_path / "bad")]) == 2
    err = capsys.readouterr().err
    assert "--fit" in err and not (tmp_path / "bad").exists()


needs_extra = pytest.mark.skipif(not segmenter_available(), reason=f"the optional extra {PHOTO_EXTRA} is not installed")


@pytest.fixture
def offline(monkeypatch):
    """No network: any socket connection fails (the segmenter must use the models inside its wheel)."""
    def refuse(*args, **kwargs):
        raise OSError("the network was used")

    monkeypatch.setattr(socket.socket, "connect", refuse)


@needs_extra
def test_the_person_mask_finds_a_generated_body_offline(offline, body_png):
    _, _, image = body_png
    exact = np.abs(image).max(-1) > 0.5 / 255
    found = person_mask(image)
    assert found.shape == exact.shape and 0 <= found.min() and found.max() <= 1
    assert float(mask_iou(found >= SILHOUETTE_THRESHOLD, exact)) > 0.6


@needs_extra
def test_reconstruct_with_an_automatic_mask_writes_the_mask_beside_the_result(offline, body_png, tmp_path):
    image, _, _ = body_png
    result = Run.load("human").reconstruct_images([image], tmp_path / "rec", masks="auto", viewer_images=0)
    written = Image.open(tmp_path / "rec" / "body_mask.png")
    assert written.size == Image.open(image).size and written.mode == "L"
    assert (tmp_path / "rec" / "body_steps.png").is_file() and result.silhouette_ious[0] > 0.5
