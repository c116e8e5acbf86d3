"""experiments/depth/depth_oracle.py: the oracle that triangulates each part's rays."""
from __future__ import annotations

import importlib.util

import torch

from tests.support.paths import REPO

SCRIPT = REPO / "experiments" / "depth" / "depth_oracle.py"


def test_depth_oracle_triangulates_rays_to_their_common_point():
    spec = importlib.util.spec_from_file_location("depth_oracle", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    point = torch.tensor([[0.1, -0.2, 0.3], [0.0, 0.5, -0.1]], dtype=torch.float64)  # 2 parts
    origins = torch.tensor([[0.0, 0.0, 3.0], [3.0, 0.0, 0.0], [-2.0, 1.0, -2.0]], dtype=torch.float64)
    dirs = torch.nn.functional.normalize(point.unsqueeze(0) - origins.unsqueeze(1), dim=-1)
    torch.testing.assert_close(module.triangulate(origins, dirs), point)
