"""cerberus-metrics: voxel IoU (Kato et al. 32^3 protocol), Chamfer-L2 and F-score for meshes.

Quick start::

    from cerberus_metrics import voxel_iou
    iou = voxel_iou([part0, part1], "gt.obj")          # kato protocol, 32^3
    iou = voxel_iou("pred.ply", "gt.ply", protocol="gt_bbox", resolution=64)
"""

from importlib.metadata import version as _version

from .api import (
    METRICS,
    chamfer_l2,
    evaluate_pair,
    fscore,
    inspect_mesh,
    voxel_iou,
    voxel_iou_clamped,
    voxelize,
)
from .cache import GridCache
from .errors import MeasurementError, MetricsError
from .io import Mesh, MeshInputError, MeshQualityWarning, MeshReport, OpenMeshError, load_mesh, load_parts
from .protocols import PROTOCOLS, Frame, Protocol, get_protocol, make_frame
from .voxelize import PartGrids, VoxelGrid, grid_iou

__version__ = _version("cerberus-metrics")

__all__ = [
    "METRICS",
    "PROTOCOLS",
    "Frame",
    "GridCache",
    "MeasurementError",
    "Mesh",
    "MeshInputError",
    "MeshQualityWarning",
    "MeshReport",
    "MetricsError",
    "OpenMeshError",
    "PartGrids",
    "Protocol",
    "VoxelGrid",
    "chamfer_l2",
    "evaluate_pair",
    "fscore",
    "get_protocol",
    "grid_iou",
    "inspect_mesh",
    "load_mesh",
    "load_parts",
    "make_frame",
    "voxel_iou",
    "voxel_iou_clamped",
    "voxelize",
]
