"""Pure-PyTorch rasterizer backend for Cerberus (entry point ``cerberus.renderers: torch``)."""
from cerberus_render_torch.rasterize import TorchRenderer, rasterize

__all__ = ["TorchRenderer", "rasterize"]
__version__ = "0.1.0"
