"""Pure-PyTorch rasterizer backend for Cerberus (entry point ``cerberus.renderers: torch``)."""
from importlib.metadata import version as _version

try:  # first: a `cerberus_core` of another project (same name on the public index) must fail in one line
    from cerberus_core.release import require_lockstep
except ImportError:
    raise ImportError("cerberus-render-torch: the installed `cerberus-core` is not the Cerberus toolkit's (an unrelated project has "
                      "that name on the public package index); pip uninstall cerberus-core, then install the toolkit's "
                      "packages together from its wheelhouse (README, 'Installing with pip')") from None
require_lockstep("cerberus-render-torch")

from cerberus_render_torch.rasterize import TorchRenderer, rasterize

__all__ = ["TorchRenderer", "rasterize"]
__version__ = _version("cerberus-render-torch")
