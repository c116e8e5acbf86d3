"""The interactive 3D viewer (cerberus_core.eval.viewer): the page, its vendored three.js, and the page in a
real headless Chromium from file:// and over HTTP (skipped, saying so, where Chromium is missing)."""
from __future__ import annotations

import functools
import html
import http.server
import json
import os
import re
import shutil
import threading

import numpy as np
import pytest
import torch
import trimesh
from PIL import Image

from cerberus_core.bodies.primitives import PrimitiveBodySource, sample_subjects
from cerberus_core.eval import viewer
from cerberus_core.parts import PartSet, transfer_pose
from cerberus_core.render.camera import Camera
from tests.support.oracle import body_parts
from tests.support.viewer import page_data

STEMS = ["alpha", "beta", "gamma"]


@pytest.fixture(scope="module")
def batch():
    """Three capsule bodies, their exact part reconstructions, cameras and grey input pictures."""
    subject = sample_subjects(1, seed=3, split="test")[0]
    bodies = list(PrimitiveBodySource().posed_bodies(subject, [0, 1, 2]))
    recon = PartSet.cat([body_parts(b, seed=i) for i, b in enumerate(bodies)])
    camera = Camera.look_at(torch.tensor([30.0, 100.0, 200.0]), torch.full((3,), 15.0), torch.full((3,), 2.6),
                            fov_y_deg=torch.full((3,), 30.0), image_size=32)
    images = torch.linspace(0.3, 0.9, 3)[:, None, None, None].expand(3, 3, 32, 32).contiguous()
    return {"bodies": bodies, "recon": recon, "camera": camera, "images": images}


@pytest.fixture(scope="module")
def page(batch, tmp_path_factory):
    out = tmp_path_factory.mktemp("viewer")
    written = viewer.write_reconstruction_viewer(out, batch["images"], batch["recon"], batch["camera"], STEMS,
                                                 viewer.ViewerPage(limit=2, limit_hint="--viewer-images"),
                                                 viewer.CardDetails(bodies=batch["bodies"]))
    return out, written


def status(dom: str) -> dict:
    m = re.search(r'<pre id="viewer-status"[^>]*>(.*?)</pre>', dom, re.S)
    assert m and m.group(1), "the page never published its status (did its module script run?)"
    return json.loads(html.unescape(m.group(1)))


def glb_mesh_count(path) -> int:
    return len(trimesh.load(path, force="scene").geometry)


# ------------------------------------------------------------------ without a browser
def test_vendored_three_is_pinned_and_licensed() -> None:
    assert viewer.THREE_DIR.name == f"three-{viewer.THREE_VERSION}"
    assert "MIT License" in (viewer.THREE_DIR / "LICENSE").read_text()
    assert viewer.THREE_DIR.parent == viewer.VENDOR and viewer.VENDOR.name == "vendor"
    readme = (viewer.VENDOR / "README.md").read_text()
    assert f"three.js {viewer.THREE_VERSION}" in readme.replace("**", "") and "MIT" in readme
    for path in viewer.THREE_FILES:
        assert (viewer.THREE_DIR / path).is_file(), path


def test_vendored_modules_import_only_each_other() -> None:
    modules = viewer.vendored_modules()
    assert "three" in modules
    for spec, src in modules.items():
        for m in re.finditer(r"""\b(?:import|export)\s*(?:[\w*{}\s,$]+?\s*from\s*)?["']([^"']+)["']""", src):
            line = src[src.rfind("\n", 0, m.start()) + 1:m.start()].lstrip()
            if line.startswith(("*", "//", "/*")):  # a comment, e.g. "@three_import import ... from '...'"
                continue
            assert m.group(1) in modules, f"{spec} imports {m.group(1)!r}, which the import map lacks"


def test_page_writes_glbs_and_bounds_its_entries(page, batch) -> None:
    out, written = page
    names = sorted(p.name for p in written)
    assert names == sorted(["alpha.glb", "alpha_gt.glb", "alpha_new_pose.glb", "beta.glb", "beta_gt.glb",
                            "beta_new_pose.glb", "index.html"])  # limit 2: gamma is left out ...
    text = (out / "index.html").read_text()
    assert "The first 2 of 3 images (--viewer-images sets how many)." in text  # ... and the page says so
    assert text.count('<section class="card"') == 2
    assert "https://" not in text.split('<script type="module">')[1] and "fetch(" not in text  # all inline
    assert (out / "index.html").stat().st_size < 3_000_000
    gt = trimesh.load(out / "alpha_gt.glb", force="scene")
    assert sorted(gt.geometry) == sorted(batch["bodies"][0].part_names)
    assert sum(len(g.faces) for g in gt.geometry.values()) == len(batch["bodies"][0].faces)
    # the new pose: alpha's parts with the rotations and translations of the next image, beta
    want = transfer_pose(batch["recon"].index([0]), batch["recon"].index([1])).posed()[0].numpy()
    posed = trimesh.load(out / "alpha_new_pose.glb", force="scene")
    np.testing.assert_allclose(np.stack([posed.geometry[f"part_{k:02d}"].vertices for k in range(10)]), want,
                               atol=1e-5)


def test_part_labels_and_ious_reach_the_page(batch, tmp_path) -> None:
    """Issue 34: the viewer named every learned part ``part_05`` where the card or the evaluation knows it is the
    head, and showed no image's IoU."""
    labels = ["head", None, *[f"segment {k}" for k in range(2, 10)]]
    viewer.write_reconstruction_viewer(tmp_path, batch["images"], batch["recon"], batch["camera"], STEMS,
                                       viewer.ViewerPage(part_labels=labels),
                                       viewer.CardDetails(bodies=batch["bodies"], ious=[0.5, None, 0.25]))
    data = page_data(tmp_path / "index.html")
    assert data["part_labels"] == {"part_00": "head", **{f"part_{k:02d}": f"segment {k}" for k in range(2, 10)}}
    assert [e["iou"] for e in data["entries"]] == [0.5, None, 0.25]
    text = (tmp_path / "index.html").read_text()
    assert "Input · voxel IoU 0.500" in text and "Input · voxel IoU 0.250" in text and text.count("voxel IoU") == 2
    for page, details, match in ((viewer.ViewerPage(part_labels=["head"]), None, "10 parts but 1 part labels"),
                                 (None, viewer.CardDetails(ious=[0.5]), "3 reconstructions but 1 IoUs"),
                                 (viewer.ViewerPage(part_labels=["head"] * 9 + ["x\x1b[2J"]), None, None)):
        args = (tmp_path, batch["images"], batch["recon"], batch["camera"], STEMS, page, details)
        if match is None:  # a hostile label is escaped, not refused
            viewer.write_reconstruction_viewer(*args)
            assert "\x1b" not in (tmp_path / "index.html").read_text()
            continue
        with pytest.raises(ValueError, match=match):
            viewer.write_reconstruction_viewer(*args)


def test_limit_zero_writes_nothing(batch, tmp_path) -> None:
    assert viewer.write_reconstruction_viewer(tmp_path, batch["images"], batch["recon"], batch["camera"], STEMS,
                                              viewer.ViewerPage(limit=0)) == []
    assert not any(tmp_path.iterdir())


def test_one_image_has_no_new_pose_and_camera_view_inverts_look_at(batch, tmp_path) -> None:
    one = batch["recon"].index([0])
    cam = batch["camera"].index([0])
    viewer.write_reconstruction_viewer(tmp_path, batch["images"][:1], one, cam, ["solo"])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["index.html", "solo.glb"]
    view = viewer.camera_view(cam)
    assert view == pytest.approx({"azimuth": 30.0, "elevation": 15.0, "distance": 2.6, "fov_y": 30.0}, abs=1e-4)


def test_write_viewer_takes_picture_files(tmp_path, batch) -> None:
    Image.new("RGB", (8, 8), (200, 10, 10)).save(tmp_path / "in.png")
    viewer.write_reconstruction_viewer(tmp_path, batch["images"][:1], batch["recon"].index([0]),
                                       batch["camera"].index([0]), ["x"])
    path = viewer.write_viewer(tmp_path, [viewer.ViewerEntry("x", tmp_path / "in.png", tmp_path / "x.glb")],
                               viewer.ViewerPage(title="a <title>"), filename="other.html")
    text = path.read_text()
    assert "All 1 image(s)." in text and "a &lt;title&gt;" in text
    with pytest.raises(ValueError, match="no entries"):
        viewer.write_viewer(tmp_path, [])


# ------------------------------------------------------------------ in a real browser
def test_page_loads_from_file_url_with_every_part(page, chromium) -> None:
    out, _ = page
    dom, console = chromium.dump_dom((out / "index.html").as_uri())
    assert console == [], f"console messages: {console}"
    st = status(dom)
    assert st["ready"] and st["errors"] == [], st
    assert 'data-viewer="ready"' in dom
    for card, stem in zip(st["cards"], STEMS[:2], strict=True):
        assert card["name"] == stem
        assert card["meshCounts"] == {"reconstruction": glb_mesh_count(out / f"{stem}.glb"),
                                      "ground_truth": glb_mesh_count(out / f"{stem}_gt.glb"),
                                      "new_pose": glb_mesh_count(out / f"{stem}_new_pose.glb")}
    assert st["meshCount"] == 2 * 10  # window.cerberusViewer.meshCount: the reconstructions' part meshes
    assert dom.count('type="checkbox"') == 2 * 10  # a toggle per part of the shown model


def test_part_toggles_say_the_labels_of_learned_parts_only(batch, chromium, tmp_path) -> None:
    labels = ["head", None, *[f"segment {k}" for k in range(2, 10)]]
    viewer.write_reconstruction_viewer(tmp_path, batch["images"][:2], batch["recon"].index([0, 1]),
                                       batch["camera"].index([0, 1]), STEMS[:2], viewer.ViewerPage(part_labels=labels),
                                       viewer.CardDetails(bodies=batch["bodies"][:2], ious=[0.5, None]))
    want = ["head (part_00)", "part_01", *[f"segment {k} (part_{k:02d})" for k in range(2, 10)]]
    for model, names in (("reconstruction", [want] * 2), ("new_pose", [want] * 2),
                         ("ground_truth", [sorted(b.part_names) for b in batch["bodies"][:2]])):
        dom, console = chromium.dump_dom((tmp_path / "index.html").as_uri() + f"#model={model}")
        st = status(dom)
        assert console == [] and st["ready"] and st["errors"] == [], (console, st)
        assert [sorted(c["parts"]) if model == "ground_truth" else c["parts"] for c in st["cards"]] == names, model
        assert [c["iou"] for c in st["cards"]] == [0.5, None]


def test_page_loads_over_http(page, chromium) -> None:
    out, _ = page

    class Quiet(http.server.SimpleHTTPRequestHandler):
        def log_message(self, *args) -> None:
            pass

    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), functools.partial(Quiet, directory=str(out)))
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        # the hash picks the model and light every card opens with
        dom, console = chromium.dump_dom(f"http://127.0.0.1:{server.server_address[1]}/index.html"
                                         "#model=ground_truth&light=new")
    finally:
        server.shutdown()
        server.server_close()
    assert console == [], f"console messages: {console}"
    st = status(dom)
    assert st["ready"] and st["errors"] == [] and st["meshCount"] == 20, st
    assert [(c["shown"], c["light"]) for c in st["cards"]] == [("ground_truth", "new")] * 2
    assert dom.count('type="checkbox"') == sum(c["meshCounts"]["ground_truth"] for c in st["cards"])


def test_screenshot_shows_the_parts(page, chromium, tmp_path) -> None:
    out, _ = page
    dom, _ = chromium.dump_dom((out / "index.html").as_uri())  # the same window size as the screenshot
    rect = status(dom)["cards"][0]["canvas"]
    shot = tmp_path / "viewer.png"  # CERBERUS_KEEP_SCREENSHOT=path keeps a copy to look at
    console = chromium.screenshot((out / "index.html").as_uri(), shot)
    assert console == [], f"console messages: {console}"
    if os.environ.get("CERBERUS_KEEP_SCREENSHOT"):
        shutil.copy(shot, os.environ["CERBERUS_KEEP_SCREENSHOT"])
    img = np.asarray(Image.open(shot).convert("RGB"), dtype=np.float64)
    x, y, w, h = (int(round(rect[k])) for k in ("x", "y", "width", "height"))
    assert y + h <= img.shape[0], "the first card's 3D view is below the screenshot"
    view = img[y + 2:y + h - 2, x + 2:x + w - 2]
    assert view.std() > 10, "the 3D view is blank"
    saturation = view.max(-1) - view.min(-1)
    assert (saturation > 60).mean() > 0.01, "no coloured parts in the 3D view"


# ------------------------------------------------------------------ hostile names (issue 20)
HOSTILE = ["<!--<script>.png", "\"'><img src=x onerror=\"document.title='pwned'\">.png",
           ("n" * 120 + "</script><script>document.title='pwned'</script><!--" + "m" * 300)[:300]]


@pytest.fixture(scope="module")
def hostile_page(batch, tmp_path_factory):
    """Three cards named with HTML and script syntax (one 300 characters long), and such a title."""
    out = tmp_path_factory.mktemp("hostile")
    glbs = viewer.write_reconstruction_viewer(out, batch["images"], batch["recon"], batch["camera"], STEMS,
                                              viewer.ViewerPage(limit=3))
    entries = [viewer.ViewerEntry(name, batch["images"][i], out / f"{STEMS[i]}.glb", note=f"from {name}",
                                  camera=viewer.camera_view(batch["camera"].index([i])))
               for i, name in enumerate(HOSTILE)]
    path = viewer.write_viewer(out, entries, viewer.ViewerPage(title="<!--</title><script>document.title='pwned'</script>"),
                               filename="hostile.html")
    assert glbs
    return path


def test_hostile_names_stay_text_in_the_page(hostile_page) -> None:
    text = hostile_page.read_text()
    data = text.split('id="cerberus-viewer-data">', 1)[1].split("</script>", 1)[0]
    assert "<" not in data and ">" not in data  # nothing in the data can end or reopen a script element
    assert [e["name"] for e in json.loads(data)["entries"]] == HOSTILE  # JSON.parse gets the names back
    body = text.split("<main>", 1)[1].split("</main>", 1)[0]
    assert "<script" not in body and "<!--" not in body and "<img src=x" not in body
    assert html.escape(HOSTILE[2]) in body


def test_hostile_names_in_a_real_browser(hostile_page, chromium) -> None:
    dom, console = chromium.dump_dom(hostile_page.as_uri())
    assert console == [], f"console messages: {console}"
    st = status(dom)
    assert st["ready"] and st["errors"] == [], st
    assert [c["name"] for c in st["cards"]] == HOSTILE  # each card shows its name as text, whole
    assert dom.count('<section class="card"') == 3 and dom.count("<img") == 3  # the three input pictures only
    title = html.unescape(re.search(r"<title>(.*?)</title>", dom, re.S).group(1))
    assert title == "<!--</title><script>document.title='pwned'</script>"  # shown as text, never run
    assert st["meshCount"] == 3 * 10
