"""The assembled Cerberus model (cerberus_core.model.cerberus): output shapes, camera vs world frames,
initialisation, evaluation API, and the images it refuses (issue 26)."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from cerberus_core.model import Cerberus, ModelConfig
from cerberus_core.parts import PartSet, pose_parts
from cerberus_core.render.api import render_parts
from cerberus_core.render.backends import make_renderer
from cerberus_core.render.camera import Camera


def small_model(**kw) -> Cerberus:
    torch.manual_seed(0)
    return Cerberus(ModelConfig(width=8, shape_latent_dim=16, depth_offset=2.5, **kw))


def cameras(b=2, size=32):
    return Camera.look_at(torch.linspace(0, 120, b), 15.0, 2.5, fov_y_deg=30.0, image_size=size)


def test_reconstruct_shapes_of_every_output():
    model = small_model()
    images, cam = torch.rand(2, 3, 32, 32), cameras()
    parts = model.reconstruct(images, cam)
    assert isinstance(parts, PartSet)
    pred = model(images)
    parts_cam = model.pose(pred, cam, frame="camera")
    assert parts.posed().shape == (2, 9, 162, 3)
    assert parts_cam.posed().shape == (2, 9, 162, 3)
    assert parts.local_vertices.shape == (2, 9, 162, 3)
    assert parts.faces.shape == (320, 3) and parts.faces.dtype == torch.int64
    assert parts.rotations.shape == parts_cam.rotations.shape == (2, 9, 3, 3)
    assert parts.translations.shape == parts_cam.translations.shape == (2, 9, 3)
    assert pred.shape_latent.shape == (2, 16)
    assert pred.maps.prob.shape == pred.maps.depth_map.shape == (2, 9, 32, 32)
    with pytest.raises(ValueError, match="frame"):
        model.pose(pred, cam, frame="screen")


@pytest.mark.parametrize("rotation", ["camera", "world", "none"])
def test_world_and_camera_frames_agree(rotation):
    model = small_model(rotation=rotation)
    with torch.no_grad():
        model.rotation.linear.weight.normal_()  # non-trivial rotations
    cam = cameras()
    pred = model(torch.rand(2, 3, 32, 32))
    parts, parts_cam = model.pose(pred, cam), model.pose(pred, cam, frame="camera")
    vertices = parts.posed()
    torch.testing.assert_close(cam.camera_to_world(parts_cam.posed().flatten(1, 2)).view_as(vertices),
                               vertices, atol=1e-5, rtol=0)
    torch.testing.assert_close(parts.rotations, cam.rotation.transpose(-1, -2).unsqueeze(1) @ parts_cam.rotations)
    torch.testing.assert_close(pose_parts(parts.local_vertices, parts.rotations, parts.translations), vertices)
    # the translation projects to the expected keypoint of the probability map
    uv, depth = cam.project(parts.translations)
    prob = pred.maps.prob
    h, w = prob.shape[-2:]
    rows, cols = torch.meshgrid(torch.arange(h) + 0.5, torch.arange(w) + 0.5, indexing="ij")
    expected_u = (prob * cols).sum(dim=(-2, -1))
    torch.testing.assert_close(uv[..., 0], expected_u, atol=1e-3, rtol=0)


def test_initial_parts_are_visible_spread_and_near_the_origin():
    model = small_model()
    cam = cameras(2, 64)
    parts = model.reconstruct(torch.rand(2, 3, 64, 64), cam)
    assert parts.translations.abs().max() < 0.5  # inside the unit cube where bodies are
    gaps = torch.cdist(parts.translations, parts.translations) + 9 * torch.eye(9)
    assert gaps.min() > 0.05  # each part starts at its own anchor
    out = render_parts(make_renderer("torch"), parts.posed().detach(), parts.faces, cam)
    coverage = out.alpha.mean(dim=(1, 2, 3))
    assert (coverage > 0.02).all()


def test_no_rotation_head_fixes_world_rotation_to_identity():
    model = small_model(num_parts=1, sphere_level=3, rotation="none")
    cam = cameras()
    parts = model.reconstruct(torch.rand(2, 3, 32, 32), cam)
    assert parts.posed().shape == (2, 1, 642, 3)
    torch.testing.assert_close(parts.rotations, torch.eye(3).expand(2, 1, 3, 3))
    parts_cam = model.pose(model(torch.rand(2, 3, 32, 32)), cam, frame="camera")
    torch.testing.assert_close(parts_cam.rotations, cam.rotation.unsqueeze(1))


def test_world_rotation_head_starts_at_the_identity_and_turns_parts_alike_in_every_view():
    """``model.rotation: world``: the head's rotation is the part's world rotation, so an untrained model's parts are
    unturned whatever the camera (the paper's camera-relative head turns them with the camera), and two views that
    predict the same quaternion place the same world part; the camera frame follows from the world one."""
    images, cam = torch.rand(2, 3, 32, 32), cameras()  # azimuths 0 and 120
    world = small_model(rotation="world")
    torch.testing.assert_close(world.reconstruct(images, cam).rotations, torch.eye(3).expand(2, 9, 3, 3),
                               atol=0.1, rtol=0)  # the head starts near the identity quaternion
    camera = small_model(rotation="camera")
    turned = camera.reconstruct(images, cam).rotations
    assert (turned[0] - turned[1]).abs().amax() > 0.5  # the camera-relative head turns the parts with the camera
    with torch.no_grad():
        world.rotation.linear.weight.zero_()
        world.rotation.linear.bias.copy_(torch.randn(9 * 4))
    pred = world(images)
    parts, parts_cam = world.pose(pred, cam), world.pose(pred, cam, frame="camera")
    torch.testing.assert_close(parts.rotations[0], parts.rotations[1])
    torch.testing.assert_close(parts.rotations, pred.rotations)
    torch.testing.assert_close(parts_cam.rotations, cam.rotation.unsqueeze(1) @ parts.rotations)
    parts.posed().sum().backward()  # the head learns from the world-frame parts
    assert world.rotation.linear.bias.grad.abs().sum() > 0


def test_forward_mixer_replaces_the_render_latent_only():
    model = small_model()
    pred = model(torch.rand(4, 3, 32, 32), mix=lambda s: s.flip(0))
    torch.testing.assert_close(pred.render_latent, pred.shape_latent.flip(0))
    torch.testing.assert_close(pred.local_vertices, model.shape.deform(pred.shape_latent.flip(0)))



def test_reconstruct_refuses_images_that_are_not_float32_in_0_1(human_run):
    cam = human_run.scene.cameras(torch.zeros(1), 64)
    with pytest.raises(ValueError, match=r"uint8 \(0-255\); pass images.float\(\) / 255"):
        human_run.model.reconstruct(torch.zeros(1, 3, 64, 64, dtype=torch.uint8), cam)
    with pytest.raises(ValueError, match="float64"):
        human_run.model.reconstruct(torch.zeros(1, 3, 64, 64, dtype=torch.float64), cam)
    with pytest.raises(TypeError, match=r"images: got ndarray .*; pass a torch.Tensor .* torch.from_numpy"):
        human_run.model.reconstruct(np.zeros((1, 3, 64, 64), np.float32), cam)  # it said "the images are float32"
    with pytest.raises(ValueError, match="above 1"):
        human_run.model.reconstruct(torch.full((1, 3, 64, 64), 200.0), cam)
    human_run.model.eval()
    with torch.no_grad():
        assert human_run.model.reconstruct(torch.rand(1, 3, 64, 64), cam).batch_size == 1


@pytest.mark.parametrize(("dtype", "words"), [
    (torch.uint8, r"Cerberus: the images are uint8 \(0-255\); pass images.float\(\) / 255"),
    (torch.float64, r"Cerberus: the images are torch.float64; pass images.float\(\)"),
], ids=["uint8", "float64"])
def test_forward_names_images_of_another_dtype_than_the_weights(human_run, dtype, words):
    """Issue 34 campaign: ``model(uint8 images)`` was a RuntimeError inside the first convolution."""
    with pytest.raises(ValueError, match=words):
        human_run.model(torch.zeros(1, 3, 64, 64, dtype=dtype))
