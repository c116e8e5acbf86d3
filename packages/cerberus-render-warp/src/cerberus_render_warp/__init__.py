"""NVIDIA Warp renderer backend for Cerberus (entry point ``cerberus.renderers: warp``).

Rasterization and the differentiable shading (forward and backward) run as Warp kernels on the
tensors' device (CPU, or the matching CUDA device), zero-copy with torch. Importing this package
needs ``warp-lang``; the error names the package to install if it is missing. The ops are the functions
(``rasterize``, ``shade``, ``vertex_normals``, ``antialias``, ``nearest_indices``); their autograd Functions are
private to their modules, as nvdiffrast keeps its own.
"""
from importlib.metadata import version as _version

try:  # first, so that another project's `cerberus_core` (same name on the public index) fails in one line
    from cerberus_core.release import require_lockstep
except ImportError:
    raise ImportError("cerberus-render-warp: the installed cerberus-core is not the Cerberus toolkit's; pip uninstall cerberus-core, then install from the toolkit's wheelhouse (README, 'Installing with pip')") from None
require_lockstep("cerberus-render-warp")

from cerberus_render_warp.antialias import antialias
from cerberus_render_warp.nearest import nearest_indices
from cerberus_render_warp.normals import vertex_normals
from cerberus_render_warp.rasterize import rasterize
from cerberus_render_warp.renderer import WarpRenderer
from cerberus_render_warp.shade import shade

__all__ = ["WarpRenderer", "antialias", "nearest_indices", "rasterize", "shade", "vertex_normals"]
__version__ = _version("cerberus-render-warp")
