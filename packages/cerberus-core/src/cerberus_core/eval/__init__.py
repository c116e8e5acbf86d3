"""Evaluation and use of a trained model (see docs/evaluation.md).

* :mod:`.reconstruction` — :class:`PartSet`, the model's output as plain tensors, and
  :func:`transfer_pose` (one image's parts, another's rotations and translations).
* :mod:`.standard` — voxel IoU of the union of parts (metric found through ``cerberus.metrics``).
* :mod:`.hard` — the identity-conditional "Hard Human" test.
* :mod:`.part_quality` — consistency of the learned parts with the ground-truth semantic parts.
* :mod:`.visibility` — how often each learned part is wholly hidden in its own input view.
* :mod:`.runner` — :func:`evaluate_dataset`: all of the above in one pass over a test set.
* :mod:`.report` — JSON and Markdown.
* :mod:`.export` — GLB / OBJ files of posed parts.
* :mod:`.figures` — Figure 1 (b)-(f), Table 2, turntables.
* :mod:`.images` — reading user images for ``cerberus reconstruct``.
"""
from cerberus_core.parts import PartSet, transfer_pose

__all__ = ["PartSet", "transfer_pose"]
