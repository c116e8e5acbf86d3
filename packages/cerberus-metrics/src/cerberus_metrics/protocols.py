"""Named voxel-IoU protocols: the coordinate frame and the voxelization rule.

A protocol fixes two things:

* the **frame**: an affine map from mesh coordinates ``v`` to lattice coordinates
  ``p = v * scale + shift`` (one lattice unit = one voxel edge; voxel ``i`` spans
  ``[i, i + 1)``), and which lattice box is the evaluation grid;
* the **rule** that turns a triangle surface into solid voxels:
  ``"surface"`` (Kato et al.: voxels touched by the surface, then the 6-connected
  exterior flood fill) or ``"center"`` (a voxel is solid when its centre is inside
  the surface by the non-zero winding rule).

Protocols (see docs/metrics.md for the full specification):

``kato`` (default)
    Kato et al. (Neural 3D Mesh Renderer / mesh_reconstruction) evaluation.
    Fixed frame: shapes live in ``[-0.5, 0.5]^3``; ``p = R * (v * (R - 1) / R + 0.5)``,
    i.e. the 31/32 scaling at R = 32. Grid ``[0, R)^3``; a mesh leaving it is an error, unless a
    prediction is clamped to it (``outside="clamp"``).
``gt_bbox``
    The ``surface`` rule in a frame normalised by the ground truth: the GT's bounding
    box is centred and its longest side scaled to 1, then mapped as in ``kato``
    (identical to Kato's ``voxelize(..., normalize=True)``, but with the normalisation
    computed on the GT and applied to both meshes). The lattice grows to hold a
    prediction that extends beyond the GT's grid.
``gt_bbox_center``
    As ``gt_bbox`` with the ``center`` rule: an unbiased volume estimate.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from .io import MeshInputError

__all__ = ["Protocol", "Frame", "PROTOCOLS", "get_protocol", "make_frame", "lattice_box"]

#: Largest lattice (voxels) a ``gt_bbox`` frame may grow to for a prediction larger than the
#: ground truth (2^28 voxels = 256 MiB per bool grid). A prediction that needs more differs from
#: the ground truth in scale or placement by an order of magnitude or more (at R = 32: >= 20x).
MAX_GRID_VOXELS = 2**28

Rule = Literal["surface", "center"]
FrameKind = Literal["unit", "gt_bbox"]


@dataclass(frozen=True)
class Protocol:
    """A named evaluation protocol (frame + rule)."""

    name: str
    frame: FrameKind
    rule: Rule
    summary: str


PROTOCOLS: dict[str, Protocol] = {
    p.name: p
    for p in (
        Protocol(
            "kato",
            "unit",
            "surface",
            "Kato et al./PTN: shapes in [-0.5,0.5]^3, (R-1)/R scaling, surface voxels from axis-aligned ray "
            "hits + vertex voxels, exterior 6-connected flood fill, interior = complement.",
        ),
        Protocol(
            "gt_bbox",
            "gt_bbox",
            "surface",
            "kato rule after normalising both meshes by the ground truth's bounding box "
            "(centred, longest side 1).",
        ),
        Protocol(
            "gt_bbox_center",
            "gt_bbox",
            "center",
            "voxel-centre rule (non-zero winding number, 3-axis majority) after normalising both meshes by the "
            "ground truth's bounding box.",
        ),
    )
}


def get_protocol(name: str | Protocol) -> Protocol:
    """Look up a protocol by name; the error lists the valid names."""
    if isinstance(name, Protocol):
        return name
    try:
        return PROTOCOLS[name]
    except KeyError:
        raise MeshInputError(f"unknown protocol {name!r}; choose one of: {', '.join(PROTOCOLS)}") from None


def check_resolution(resolution: int) -> int:
    if isinstance(resolution, bool) or not isinstance(resolution, (int, np.integer)) or not 2 <= resolution <= 1024:
        raise MeshInputError(f"resolution must be an integer in [2, 1024] (e.g. 32, 64, 128), got {resolution!r}")
    return int(resolution)


@dataclass(frozen=True)
class Frame:
    """Affine map from mesh coordinates to lattice coordinates, ``p = v * scale + shift``.

    scale: lattice units per mesh unit (1 / voxel edge length in mesh units).
    shift: (3,) lattice coordinate of the mesh-space origin.
    resolution: R, the evaluation grid is ``[0, R)^3`` in lattice coordinates.
    fixed: True for the ``unit`` frame, whose grid may not grow.
    """

    scale: float
    shift: tuple[float, float, float]
    resolution: int
    fixed: bool

    @property
    def pitch(self) -> float:
        """Voxel edge length in mesh units."""
        return 1.0 / self.scale

    def to_lattice(self, points: np.ndarray) -> np.ndarray:
        """Map (..., 3) mesh coordinates to lattice coordinates (same shape, float64)."""
        return points * self.scale + np.asarray(self.shift)

    def to_mesh(self, lattice: np.ndarray) -> np.ndarray:
        """Inverse of :meth:`to_lattice`."""
        return (np.asarray(lattice, dtype=np.float64) - np.asarray(self.shift)) / self.scale


def make_frame(protocol: Protocol, resolution: int, gt_vertices: np.ndarray | None = None) -> Frame:
    """Build the frame of ``protocol`` at ``resolution``; ``gt_bbox`` frames need ``gt_vertices`` (V, 3)."""
    r = check_resolution(resolution)
    if protocol.frame == "unit":
        # Kato: p = R * (v * (R-1)/R + 0.5) = (R-1) v + R/2, computed in float64.
        return Frame(float(r - 1), (r / 2.0,) * 3, r, True)
    if gt_vertices is None:
        raise MeshInputError(f"protocol {protocol.name!r} normalises by the ground truth; pass gt_vertices")
    lo = np.array([gt_vertices[:, i].min() for i in range(3)])  # column-wise: faster than min(axis=0)
    hi = np.array([gt_vertices[:, i].max() for i in range(3)])
    extent = float((hi - lo).max())
    if not extent > 0:
        raise MeshInputError(
            f"protocol {protocol.name!r}: the ground truth has a zero-size bounding box, so it cannot be "
            "normalised; check the ground-truth mesh"
        )
    scale = (r - 1) / extent
    centre = (lo + hi) / 2.0
    if not np.isfinite(scale) or extent < 1e-12 * float(np.abs(centre).max()):
        raise MeshInputError(
            f"protocol {protocol.name!r}: the ground truth's size ({extent:.3g}) is too small to normalise "
            f"{'(the scale overflows)' if not np.isfinite(scale) else f'relative to its position {centre.tolist()}'}"
            ": its coordinates cannot resolve a voxel; check the ground-truth mesh's units"
        )
    shift = r / 2.0 - centre * scale
    return Frame(scale, tuple(float(s) for s in shift), r, False)


def lattice_box(frame: Frame, bounds: np.ndarray, names: Sequence[str],
                ground_truth: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """The lattice box ``[lo, hi)`` (two (3,) int64) holding the voxels of several meshes.

    bounds: (P, 2, 3) per-mesh (min, max) lattice coordinates; names: P names for messages.
    Meshes within ``[0, R]^3`` give the grid ``[0, R)^3``. Otherwise fixed frames raise,
    naming the mesh (the protocol assumes normalised shapes), and other frames return the
    grid extended to the meshes plus one empty voxel of margin, so no prediction is clipped.
    ground_truth: the meshes are a ground truth, which is never clamped: the fixed frame's error
    then says to normalise it (or to use the ``gt_bbox`` protocol) instead of ``outside="clamp"``.
    """
    r = frame.resolution
    outside = (bounds[:, 0] < 0).any(axis=1) | (bounds[:, 1] > r).any(axis=1)
    if not outside.any():
        return np.zeros(3, np.int64), np.full(3, r, np.int64)
    if frame.fixed:
        k = int(np.flatnonzero(outside)[0])
        g0, g1 = frame.to_mesh(np.zeros(3)), frame.to_mesh(np.full(3, float(r)))
        vmin, vmax = frame.to_mesh(bounds[k, 0]), frame.to_mesh(bounds[k, 1])
        fix = (
            "a ground truth is never clamped: normalise it to [-0.5, 0.5]^3, or score meshes in other coordinates "
            "with the gt_bbox protocol (normalised by the ground truth)"
            if ground_truth
            else "pass outside='clamp' to clamp it to the grid (its voxels outside are dropped and the part is "
            "counted, as evaluation does), or normalise the mesh to [-0.5, 0.5]^3"
        )
        raise MeshInputError(
            f"{names[k]}: mesh lies (partly) outside the kato grid: coordinates must be within "
            f"[{g0.min():.4f}, {g1.max():.4f}]^3 (shapes normalised to [-0.5, 0.5]^3), found "
            f"min {np.round(vmin, 4).tolist()} max {np.round(vmax, 4).tolist()}; {fix}"
        )
    if not np.isfinite(bounds).all():
        raise MeshInputError(
            f"{names[int(np.flatnonzero(outside)[0])]}: lattice coordinates overflow in the ground-truth frame; "
            "the mesh's scale is absurd compared with the ground truth's: check the units of both meshes"
        )
    lo = np.minimum(np.floor(bounds[:, 0].min(axis=0)) - 1, 0)
    hi = np.maximum(np.floor(bounds[:, 1].max(axis=0)) + 2, r)
    voxels = float(np.prod(hi - lo))
    if voxels > MAX_GRID_VOXELS:
        k = int(np.argmax(np.maximum(-bounds[:, 0].min(axis=1), bounds[:, 1].max(axis=1))))
        reach = float(np.abs(bounds[k] - r / 2).max()) / (r - 1)
        raise MeshInputError(
            f"{names[k]}: mesh reaches {reach:.3g} ground-truth sizes from the ground truth's centre, so the "
            f"lattice holding both would need {voxels:.3g} voxels (limit {MAX_GRID_VOXELS:.3g}); at such a scale "
            "mismatch the IoU is about 0 and says nothing: check that prediction and ground truth use the same "
            "units and placement (or lower the resolution)"
        )
    return lo.astype(np.int64), hi.astype(np.int64)
