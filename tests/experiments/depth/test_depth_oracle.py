"""experiments/depth/depth_oracle.py: the oracle that triangulates each part's rays."""
from __future__ import annotations

import importlib.util

import torch

from tests.support.paths import REPO

SCRIPT = REPO / "experiments" / "depth" / "depth_oracle.py"


def test_along_rays_keeps_each_keypoint_in_view_and_reaches_the_new_depth():
    from cerberus_core.parts import PartSet
    from cerberus_core.render.camera import Camera

    spec = importlib.util.spec_from_file_location("depth_oracle", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    camera = Camera.look_at(30.0, 15.0, 2.0, fov_y_deg=30.0, image_size=64)
    translations = torch.tensor([[[0.1, 0.0, 0.0], [-0.2, 0.3, 0.1]]])  # (1, 2, 3)
    local = torch.randn(1, 2, 5, 3) * 0.05
    parts = PartSet(local, torch.zeros(1, 3, dtype=torch.long), torch.eye(3).expand(1, 2, 3, 3), translations)
    uv, depth = camera.project(translations)
    new_depth = depth[0] + torch.tensor([0.05, -0.03])
    moved = module.along_rays(parts, camera.center[0], depth[0], new_depth)
    uv2, depth2 = camera.project(moved.translations)
    torch.testing.assert_close(uv2, uv, atol=1e-4, rtol=0)
    torch.testing.assert_close(depth2[0], new_depth, atol=1e-5, rtol=0)
    torch.testing.assert_close(moved.local_vertices, parts.local_vertices)
