"""Pure-PyTorch rasterizer backend for Cerberus (entry point ``cerberus.renderers: torch``)."""
from importlib.metadata import version as _version

try:  # first, so that another project's `cerberus_core` (same name on the public index) fails in one line
    from cerberus_core.release import require_lockstep
except ImportError:
    raise ImportError("cerberus-render-torch: the installed cerberus-core is not the Cerberus toolkit's; pip uninstall cerberus-core, then install from the toolkit's wheelhouse (README, 'Installing with pip')") from None
require_lockstep("cerberus-render-torch")

from cerberus_render_torch.rasterize import TorchRenderer, rasterize

__all__ = ["TorchRenderer", "rasterize"]
__version__ = _version("cerberus-render-torch")
