"""Issue 20 (5): input the model was not trained for is named, not silently reconstructed.

Generated test images are in the training domain and reach the model exactly as before; the same body on
a cluttered background is named out of the domain (one warning, the figure, the viewer card) and, with
its silhouette (a ``--mask`` or an RGBA cut-out's alpha), composited back onto the training background;
a body cut off by the image's edge is named too; a bad mask is one line.
"""
from __future__ import annotations

import warnings

import numpy as np
import pytest
import torch
from PIL import Image

from cerberus_core.cli import main
from cerberus_core.datasets.dataset import Dataset
from cerberus_core.datasets.looks import flat_grey
from cerberus_core.reconstruct import input_domain as D
from cerberus_core.reconstruct.images import load_image


@pytest.fixture(scope="module")
def generated(tmp_path_factory):
    """The human ``tiny`` test images as PNG files, their silhouettes, and the scene."""
    root = tmp_path_factory.mktemp("input_domain")
    assert main(["data", "generate", "--dataset", "human", "--size", "tiny", "--set", "splits.train.pairs=1",
                 "--out", str(root / "data"), "--quiet"]) == 0
    ds = Dataset.open(root / "data").views(split="test")
    images = [ds[i]["images"].numpy().transpose(1, 2, 0) for i in range(len(ds))]
    paths = []
    for i, a in enumerate(images):
        paths.append(root / f"gen{i}.png")
        Image.fromarray(_u8(a)).save(paths[-1])
    silhouettes = [(np.abs(a - np.asarray(ds.scene.background)).max(-1) > 0.5 / 255) for a in images]
    return {"root": root, "scene": ds.scene, "images": images, "paths": paths, "silhouettes": silhouettes}


def _u8(a: np.ndarray) -> np.ndarray:
    return (np.clip(a, 0, 1) * 255).round().astype(np.uint8)


def _clutter(n: int, seed: int = 0) -> np.ndarray:
    """A photo-like background: smooth colour blobs."""
    low = (np.random.default_rng(seed).random((6, 6, 3)) * 255).astype(np.uint8)
    return np.asarray(Image.fromarray(low).resize((n, n), Image.BICUBIC)) / 255.0


def _on_clutter(generated, i: int = 0) -> np.ndarray:
    a, m = generated["images"][i], generated["silhouettes"][i][..., None]
    return a * m + _clutter(a.shape[0]) * (1 - m)


def test_generated_images_are_in_domain_and_unchanged(generated):
    scene = generated["scene"]
    for path in generated["paths"]:
        new = D.prepare_input(path, 64, scene, warn=False)
        assert new.out_of_domain == "", (path, new.out_of_domain)
        before = load_image(path, 64, scene.background, warn=False)
        assert torch.equal(new.image, before.image)  # so the model reconstructs it exactly as before
    ok, reason = D.background_check(load_image(generated["paths"][0], 64, scene.background).image, scene)
    assert ok and reason == ""


def test_generated_image_reconstructs_as_before(generated):
    from cerberus_core.run import Run

    run = Run.load("human")
    model, scene = run.model, run.scene
    path = generated["paths"][0]
    cam = scene.cameras([0.0], 64)
    with torch.no_grad():
        before = model.reconstruct(load_image(path, 64, scene.background, warn=False).image[None], cam).posed()
        after = model.reconstruct(D.prepare_input(path, 64, scene, warn=False).image[None], cam).posed()
    torch.testing.assert_close(after, before, rtol=0, atol=1e-6)


@pytest.mark.parametrize("make", [
    lambda a: np.random.default_rng(1).random(a.shape),  # noise
    lambda a: np.broadcast_to(np.linspace(0, 1, a.shape[1])[None, :, None], a.shape),  # a gradient
    lambda a: _clutter(a.shape[0], 2),  # photo-like blobs
    lambda a: np.ones_like(a),  # white, for a model trained on black
], ids=["noise", "gradient", "blobs", "white"])
def test_cluttered_backgrounds_fail_the_background_check(generated, make):
    a, m = generated["images"][1], generated["silhouettes"][1][..., None]
    ok, reason = D.background_check(a * m + make(a) * (1 - m), generated["scene"])
    assert not ok and "border" in reason


def test_cluttered_photo_warns_once_and_the_mask_composites_it_back(generated):
    root = generated["root"]
    photo, mask = root / "photo.png", root / "photo_mask.png"
    Image.fromarray(_u8(_on_clutter(generated))).save(photo)
    Image.fromarray(generated["silhouettes"][0].astype(np.uint8) * 255).save(mask)

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert main(["reconstruct", "--model", "human", str(photo), str(generated["paths"][1]),
                     "--out", str(root / "plain")]) == 0
    named = [str(w.message) for w in caught if "out of the training domain" in str(w.message)]
    assert len(named) == 1 and "1 of 2 image(s)" in named[0], named  # one warning, naming the photo only
    assert "photo.png: its border is not the training background" in named[0] and "gen1" not in named[0]
    assert "`mask=MASK.png`" in named[0] and "RGBA" in named[0] and "\n" not in named[0]
    html = (root / "plain" / "index.html").read_text()
    assert html.count("Out of the training domain: its border") == 1  # the photo's card, not gen1's
    assert (root / "plain" / "photo_figure1.png").is_file()

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert main(["reconstruct", "--model", "human", str(photo), "--mask", str(mask), "--out", str(root / "masked")]) == 0
    assert not [w for w in caught if "training domain" in str(w.message)]
    assert "training domain" not in (root / "masked" / "index.html").read_text()
    seen = np.asarray(Image.open(root / "masked" / "photo_input.png"), dtype=np.int16)
    assert np.abs(seen - _u8(generated["images"][0])).max() <= 1  # the body back on the training background
    # a figure with the note is taller than one without (the note is a banner above the panels)
    assert Image.open(root / "plain" / "photo_figure1.png").height > Image.open(root / "masked" / "photo_figure1.png").height


def test_rgba_cutout_uses_its_alpha(generated):
    root = generated["root"]
    rgba = np.concatenate([_u8(_on_clutter(generated)), generated["silhouettes"][0][..., None].astype(np.uint8) * 255], -1)
    Image.fromarray(rgba, "RGBA").save(root / "cutout.png")
    li = D.prepare_input(root / "cutout.png", 64, generated["scene"], warn=False)
    assert li.out_of_domain == "" and any("alpha composited" in n for n in li.notes)
    assert np.abs(li.image.numpy().transpose(1, 2, 0) - _u8(generated["images"][0]) / 255).max() <= 1 / 255 + 1e-6


def test_small_off_centre_cutout_is_framed_like_the_training_images(generated):
    root, scene = generated["root"], generated["scene"]
    a, m = generated["images"][0], generated["silhouettes"][0]
    canvas = np.zeros((200, 300, 4), np.uint8)  # the body a quarter of the frame high, off to one side
    body = np.concatenate([_u8(a), m[..., None].astype(np.uint8) * 255], -1)
    canvas[120:184, 20:84] = body
    Image.fromarray(canvas, "RGBA").save(root / "small.png")
    li = D.prepare_input(root / "small.png", 64, scene, warn=False)
    assert li.out_of_domain == "" and any("framed to its silhouette" in n for n in li.notes)
    fg = np.abs(li.image.numpy()).max(0) > 0.1
    rows, cols = np.nonzero(fg.any(1))[0], np.nonzero(fg.any(0))[0]
    longest = max(rows[-1] - rows[0] + 1, cols[-1] - cols[0] + 1) / 64
    assert longest == pytest.approx(D.FRAMING_MEDIAN * D.projected_extent(scene), abs=0.05)
    assert abs((rows[0] + rows[-1] + 1) / 2 - 32) <= 2 and abs((cols[0] + cols[-1] + 1) / 2 - 32) <= 2


def test_a_body_cut_off_by_the_frame_is_out_of_domain(generated):
    root, scene = generated["root"], generated["scene"]
    a, m = generated["images"][0], generated["silhouettes"][0]
    rows = np.nonzero(m.any(1))[0]
    cut = (rows[0] + rows[-1]) // 2  # a portrait: head to waist, the body running along the bottom edge
    top = np.ascontiguousarray(a[:cut])
    Image.fromarray(_u8(top)).save(root / "portrait.png")
    Image.fromarray(m[:cut].astype(np.uint8) * 255).save(root / "portrait_mask.png")
    plain = D.prepare_input(root / "portrait.png", 64, scene, warn=False)
    assert "run along the image's bottom" in plain.out_of_domain and "whole body" in plain.advice
    masked = D.prepare_input(root / "portrait.png", 64, scene, root / "portrait_mask.png", warn=False)
    assert "bottom" in masked.out_of_domain and "cut off" in masked.out_of_domain
    assert D.domain_note(masked).startswith("out of the training domain: ")


def test_bad_masks_are_one_line(generated, capsys):
    root, photo = generated["root"], generated["paths"][0]
    Image.fromarray(np.zeros((32, 32), np.uint8)).save(root / "small_mask.png")
    Image.fromarray(np.zeros((64, 64), np.uint8)).save(root / "black_mask.png")
    cases = [
        (["--mask", str(root / "small_mask.png")], "is 32x32 but its image"),
        (["--mask", str(root / "missing.png")], "missing.png: no such file"),
        (["--mask", str(photo)], "is not a mask"),  # a rendered picture
        (["--mask", str(root / "black_mask.png")], "marks no pixel as the body"),
        (["--mask", str(root / "black_mask.png"), "--mask", str(root / "black_mask.png")], "--mask: 2 given for 1 image(s)"),
    ]
    for extra, expected in cases:
        out = root / "bad_out"
        assert main(["reconstruct", "--model", "human", str(photo), *extra, "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert expected in err and err.count("\n") == 1 and "Traceback" not in err, err
        assert not out.exists()  # nothing half-written


def test_mask_folder_gives_each_image_its_mask(generated, capsys):
    root = generated["root"]
    folder = root / "masks"
    folder.mkdir()
    for path, m in zip(generated["paths"][:2], generated["silhouettes"][:2], strict=True):
        Image.fromarray(m.astype(np.uint8) * 255).save(folder / path.name)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert main(["reconstruct", "--model", "human", *map(str, generated["paths"][:2]), "--mask", str(folder),
                     "--out", str(root / "folder_out"), "--viewer-images", "0"]) == 0
    assert not [w for w in caught if "training domain" in str(w.message)]
    assert main(["reconstruct", "--model", "human", str(generated["paths"][2]), "--mask", str(folder),
                 "--out", str(root / "folder_out2"), "--viewer-images", "0"]) == 2
    assert "gen2.png: no such file" in capsys.readouterr().err


def test_a_coloured_or_textured_body_is_out_of_domain_even_as_a_cutout(generated):
    """Issue 26: a clothed, coloured person, however well masked, is outside what the models learned; the
    advice fits the input (no 'give an RGBA cut-out' for a cut-out)."""
    root, scene = generated["root"], generated["scene"]
    a, m = generated["images"][0], generated["silhouettes"][0]
    assert D.appearance_check(a, scene) == (True, "")
    tinted = np.where(m[..., None], a * np.array([1.0, 0.7, 0.5]), a)
    ok, reason = D.appearance_check(tinted, scene)
    assert not ok and "coloured" in reason and "untextured grey" in reason
    noisy = np.where(m[..., None], np.clip(a * (0.7 + 0.6 * np.random.default_rng(0).random(a.shape[:2] + (1,))), 0, 1), a)
    ok, reason = D.appearance_check(noisy, scene)
    assert not ok and "textured" in reason
    rgba = np.concatenate([_u8(tinted), m[..., None].astype(np.uint8) * 255], -1)
    Image.fromarray(rgba, "RGBA").save(root / "clothed.png")
    li = D.prepare_input(root / "clothed.png", 64, scene, warn=False)
    assert "coloured" in li.out_of_domain
    assert "cut-out" not in li.advice and "coarse grey body" in li.advice
    from cerberus_core.reconstruct.write import load_inputs
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        load_inputs([root / "clothed.png"], [None], 64, scene)
    messages = [str(w.message) for w in caught]
    assert any("alpha composited over the training background" in m for m in messages)  # the input's note
    domain = [m for m in messages if "out of the training domain" in m]
    assert len(domain) == 1 and "give an RGBA cut-out" not in domain[0] and "coarse grey body" in domain[0]


def test_a_silhouette_model_gets_the_cutout_as_a_flat_silhouette(generated):
    """Issue 41: a model trained in the flat input look (``data.input_look: flat``) is shown a masked photo as it
    saw its training bodies: the body one grey level, a training body's mean grey, over the training background;
    its colour is then no reason to call it out of the domain. A shaded model gets the same cut-out as before (and the warning)."""
    root, scene = generated["root"], generated["scene"]
    a, m = generated["images"][0], generated["silhouettes"][0]
    tinted = np.where(m[..., None], a * np.array([1.0, 0.7, 0.5]), a)
    rgba = np.concatenate([_u8(tinted), m[..., None].astype(np.uint8) * 255], -1)
    Image.fromarray(rgba, "RGBA").save(root / "clothed_flat.png")
    shaded = D.prepare_input(root / "clothed_flat.png", 64, scene, warn=False)
    flat = D.prepare_input(root / "clothed_flat.png", 64, scene, look="flat", warn=False)
    assert "coloured" in shaded.out_of_domain and flat.out_of_domain == ""
    body = (shaded.image - torch.tensor(scene.background).view(3, 1, 1)).abs().amax(0) > 0.5 / 255
    assert body.sum() > 20
    assert torch.equal(flat.image[:, ~body], shaded.image[:, ~body])  # the background as it was
    grey = flat.image[:, body]
    assert torch.allclose(grey, grey[:1, :1].expand_as(grey))  # one grey level on every channel of the body
    assert float(grey[0, 0]) == pytest.approx(flat_grey(scene))  # a training body's grey, not the photo's colours
    means = [float(a[m].mean()) for a, m in zip(generated["images"], generated["silhouettes"], strict=True)]
    assert abs(np.mean(means) - flat_grey(scene)) < 0.02, means  # which is what the renders' flat look fills in
    assert any("flat silhouette" in n for n in flat.notes)
    with pytest.raises(Exception, match="input_look"):
        D.prepare_input(root / "clothed_flat.png", 64, scene, look="chalk", warn=False)


def test_one_resize_is_one_warning_in_the_reconstruct_path(generated, tmp_path):
    """Issue 34: ``cerberus reconstruct`` with a 512 px image said "downscaled 4x (box filter) from 512x512 before
    conversion" and "resized from 128x128 to 64x64" for its one resize; a framed cut-out said the window in the
    reduced pixels."""
    big = np.asarray(Image.fromarray(_u8(generated["images"][0])).resize((512, 512), Image.NEAREST))
    Image.fromarray(big).save(tmp_path / "big.png")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert main(["reconstruct", "--model", "human", str(tmp_path / "big.png"), "--out", str(tmp_path / "out"),
                     "--viewer-images", "0"]) == 0
    sizes = [str(w.message) for w in caught if "512" in str(w.message) or "128" in str(w.message)]
    assert sizes == [f"{tmp_path / 'big.png'}: resized from 512x512 to 64x64"], sizes
    cutout = np.zeros((600, 600, 4), np.uint8)  # the body small in a large RGBA canvas: framed, then resized
    cutout[100:228, 300:428] = np.concatenate([big[::4, ::4], 255 * generated["silhouettes"][0][..., None].repeat(
        2, 0).repeat(2, 1).astype(np.uint8)], -1)
    Image.fromarray(cutout, "RGBA").save(tmp_path / "cutout.png")
    li = D.prepare_input(tmp_path / "cutout.png", 64, generated["scene"], warn=False)
    framed = [n for n in li.notes if "framed" in n]
    side = int(framed[0].split("(a ")[1].split("x")[0])
    rows, cols = np.nonzero(cutout[..., 3].any(1))[0], np.nonzero(cutout[..., 3].any(0))[0]
    longest = max(rows[-1] - rows[0], cols[-1] - cols[0]) + 1  # in the file's pixels
    want = longest / (D.FRAMING_MEDIAN * D.projected_extent(generated["scene"]))
    assert abs(side - want) <= 600 // 128, (framed, want)  # the file's pixels, to the reduction's factor (4)
    assert [n for n in li.notes if "resized" in n] == [f"resized from {side}x{side} to 64x64"], li.notes
    assert not any("downscaled" in n for n in li.notes)


def test_the_photo_warning_names_the_kind_of_body_the_model_learned(generated, tmp_path):
    """Issue 34: the animal model's warning spoke of "a clothed or coloured person". The phrase is the body
    source's (``BodySource.photo_subject``), found from the model's training data (a shipped model's registry
    entry, a run's manifest); a kind not known here gets the generic phrase."""
    a, m = generated["images"][0], generated["silhouettes"][0]
    tinted = np.where(m[..., None], a * np.array([1.0, 0.7, 0.5]), a)
    said = {kind: D.appearance_check(tinted, generated["scene"], kind)[1]
            for kind in ("human", "animal", "primitives", "folder", None, "not-installed")}
    assert "a clothed or coloured person" in said["human"]
    assert "animal" in said["animal"] and "person" not in said["animal"]
    assert "figure" in said["primitives"] and "person" not in said["primitives"]
    assert said["folder"] == said[None] == said["not-installed"] and "a coloured or textured body" in said[None]
    rgba = np.concatenate([_u8(tinted), m[..., None].astype(np.uint8) * 255], -1)
    Image.fromarray(rgba, "RGBA").save(tmp_path / "coloured.png")
    for model, phrase in (("animal", "a furred, patterned or coloured animal"),
                          ("human-nmrr", "a clothed or coloured person")):  # a shipped name is not a body kind
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            assert main(["reconstruct", "--model", model, str(tmp_path / "coloured.png"),
                         "--out", str(tmp_path / model), "--viewer-images", "0"]) == 0
        domain = [str(w.message) for w in caught if "out of the training domain" in str(w.message)]
        assert len(domain) == 1 and phrase in domain[0], domain
        assert model == "human-nmrr" or "person" not in domain[0]


def _closeup(a: np.ndarray, m: np.ndarray) -> np.ndarray:
    """The head and shoulders (a square 30 % of the body high from its top, centred on the head)."""
    rows = np.nonzero(m.any(1))[0]
    side = int(0.3 * (rows[-1] - rows[0]))
    head = np.nonzero(m[rows[0]:rows[0] + side // 3].any(0))[0]
    top, left = rows[0] - 2, int(head.mean()) - side // 2
    pad = np.pad(a, ((side, side), (side, side), (0, 0)), mode="edge")
    return np.ascontiguousarray(pad[top + side:top + 2 * side, left + side:left + 2 * side])


def test_a_half_body_or_close_up_without_a_mask_is_named_cut_off(generated, tmp_path):
    """Issue 34: without a mask, a face close-up (its border only partly the training background) or a half-body
    on a photo's plain wall was named only "its border is not the training background" (and the fix offered
    was a mask), never cut off. The body is now estimated from the image alone (what differs from the training
    background or from the photo's own plain background, connected to the centre), the image is still
    reconstructed, and a whole body on a wall or a body on clutter is not called cut off."""
    scene, wall = generated["scene"], np.array([0.85, 0.8, 0.7])
    a, m = generated["images"][0], generated["silhouettes"][0]
    walled = a * m[..., None] + wall * (1 - m[..., None])
    rows = np.nonzero(m.any(1))[0]
    half = slice(0, (rows[0] + rows[-1]) // 2)
    cases = {"closeup": _closeup(a, m), "closeup_on_wall": _closeup(walled, m),
             "half_body_on_wall": np.ascontiguousarray(walled[half]), "whole_on_wall": walled,
             "on_clutter": a * m[..., None] + _clutter(a.shape[0], 3) * (1 - m[..., None])}
    said = {}
    for name, arr in cases.items():
        Image.fromarray(_u8(arr)).save(tmp_path / f"{name}.png")
        said[name] = D.prepare_input(tmp_path / f"{name}.png", 64, scene, warn=False)
    assert "the body seems to run along the image's" in said["closeup"].out_of_domain
    assert "not the training background" not in said["closeup"].out_of_domain  # the sides it crosses are left out
    assert "whole body" in said["closeup"].advice and "mask" not in said["closeup"].advice
    for name in ("closeup_on_wall", "half_body_on_wall"):
        reason = said[name].out_of_domain
        assert "not the training background" in reason and "may be cut off" in reason, (name, reason)
        assert "whole body" in said[name].advice and "mask" in said[name].advice
    assert "bottom" in said["half_body_on_wall"].out_of_domain
    for name in ("whole_on_wall", "on_clutter"):
        assert "not the training background" in said[name].out_of_domain and "cut off" not in said[name].out_of_domain
    assert D.estimated_foreground(D._array(_clutter(64, 3)), scene) is None  # a cluttered border: no estimate
    fg = D.estimated_foreground(a, scene)
    assert fg is not None and D.cut_off_sides(fg) == [] and (fg == (np.abs(a).max(-1) > 0.1)).mean() > 0.99


def test_the_new_pose_borrows_an_in_domain_pose_or_says_it_cannot(generated, tmp_path):
    """Issue 34: the new pose (Figure 1 (f), the viewer's "New pose") borrowed the next image's pose, out of the
    training domain or not, without a word. Now it borrows the next in-domain image's; where no other image is
    in the domain, it borrows a flagged one and says so (a warning, the figure's note, the viewer card)."""
    photo = tmp_path / "photo.png"
    Image.fromarray(_u8(_on_clutter(generated))).save(photo)
    gen1, gen2 = (str(p) for p in generated["paths"][1:3])
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert main(["reconstruct", "--model", "human", gen1, gen2, str(photo), "--out", str(tmp_path / "a")]) == 0
    assert not [w for w in caught if "borrows" in str(w.message)]
    page = (tmp_path / "a" / "index.html").read_text()
    assert "predicted from gen1." in page and "predicted from photo" not in page  # gen2 skips the photo for gen1
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert main(["reconstruct", "--model", "human", gen1, str(photo), "--out", str(tmp_path / "b")]) == 0
    borrowed = [str(w.message) for w in caught if "borrows" in str(w.message)]
    assert len(borrowed) == 1 and "gen1 from photo" in borrowed[0] and "\n" not in borrowed[0], borrowed
    page = (tmp_path / "b" / "index.html").read_text()
    assert "predicted from photo, which is out of the training domain" in page
    one = Image.open(tmp_path / "b" / "gen1_figure1.png")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert main(["reconstruct", "--model", "human", gen1, gen2, "--out", str(tmp_path / "c")]) == 0
    assert one.height > Image.open(tmp_path / "c" / "gen1_figure1.png").height  # the note above gen1's figure


def test_a_flat_input_takes_the_body_from_the_silhouettes_coverage(generated):
    """Issue 41: the faint ring a resize leaves around a silhouette is not body (a photo's flat body came out a pixel
    wider all round than a render's); a pixel the silhouette covers as much as one of a render's 16 samples is."""
    scene = generated["scene"]
    silhouette = np.zeros((8, 8))
    silhouette[2:6, 2:6] = 1.0
    silhouette[1, 2:6] = 0.01  # the resize's ring
    silhouette[6, 2:6] = 1 / 16  # one sample of sixteen
    image = torch.rand(3, 8, 8)  # the photo's colours: not used
    flat = D.flat_input(image, silhouette, scene)
    body = flat[0] == flat_grey(scene)
    assert body[2:7, 2:6].all() and body.sum() == 20
    assert torch.equal(flat[:, ~body], torch.zeros(3, int((~body).sum())))  # the training background (black)
