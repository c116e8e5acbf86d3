"""The mesh topology helper of the antialiasing (cerberus_core.render.antialias.edge_neighbors); the
antialiasing itself is held to its reference by the conformance suite and by tests/render_warp/test_antialias.py."""
from __future__ import annotations

import torch

from cerberus_core.render.antialias import edge_neighbors
from cerberus_core.render.templates import icosphere


def test_edge_neighbors_of_closed_and_open_meshes() -> None:
    faces = icosphere(2).faces
    nb = edge_neighbors(faces)
    assert nb.shape == faces.shape and (nb >= 0).all()
    for k in range(3):  # the face across edge k lists this face back, across the same two vertices
        a, b = faces[:, (k + 1) % 3], faces[:, (k + 2) % 3]
        other = faces[nb[:, k]]
        assert ((other == a.unsqueeze(-1)).any(-1) & (other == b.unsqueeze(-1)).any(-1)).all()
        assert (nb[nb[:, k]] == torch.arange(faces.shape[0]).unsqueeze(-1)).any(-1).all()
    assert edge_neighbors(faces.clone()) is nb  # cached by content
    assert torch.equal(edge_neighbors(torch.tensor([[0, 1, 2], [2, 1, 3]])), torch.tensor([[1, -1, -1], [-1, -1, 0]]))
