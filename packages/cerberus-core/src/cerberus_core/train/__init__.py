"""Training: settings (:mod:`.settings`), data contract and order (:mod:`.data`), objective
(:mod:`.objective`), loop (:mod:`.trainer`), checkpoints (:mod:`.checkpoint`), data parallelism
(:mod:`.distributed`) and logs (:mod:`.logs`). ``cerberus train`` drives :func:`train`."""
from cerberus_core.errors import NonFiniteError
from cerberus_core.train.checkpoint import load_checkpoint
from cerberus_core.train.settings import TrainConfig, load_config, preset_names
from cerberus_core.train.trainer import TrainResult, train

__all__ = [
    "NonFiniteError",
    "TrainConfig",
    "TrainResult",
    "load_checkpoint",
    "load_config",
    "preset_names",
    "train",
]
