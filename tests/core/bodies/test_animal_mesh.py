"""Marching cubes of the quadruped's signed distance field (cerberus_core.bodies.animal_mesh)."""
from __future__ import annotations

import numpy as np
import pytest
import trimesh

from cerberus_core.bodies.animal_mesh import marching_cubes
from tests.support.meshes import assert_closed

# --- meshing ---------------------------------------------------------------------------------------


def test_marching_cubes_closed_on_random_fields() -> None:
    rng = np.random.default_rng(0)
    for _ in range(10):  # white noise exercises every ambiguous face configuration
        f = rng.normal(size=(10, 11, 12))
        f[[0, -1]], f[:, [0, -1]], f[:, :, [0, -1]] = 1.0, 1.0, 1.0
        assert_closed(marching_cubes(f, np.zeros(3), 1.0))


def test_marching_cubes_sphere_volume() -> None:
    x = np.linspace(-1, 1, 41)
    f = np.sqrt(x[:, None, None] ** 2 + x[None, :, None] ** 2 + x[None, None, :] ** 2) - 0.7
    v, faces = marching_cubes(f, np.full(3, -1.0), x[1] - x[0])
    assert_closed((v, faces))
    assert trimesh.Trimesh(v, faces, process=False).volume == pytest.approx(4 / 3 * np.pi * 0.7**3, rel=0.02)
