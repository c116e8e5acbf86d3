"""Evaluation of a trained model on a dataset (see docs/evaluation.md).

* :mod:`.runner` — :func:`evaluate_dataset`: the standard voxel IoU and every diagnostic in one pass over a
  test set; :class:`EvalConfig`, :class:`EvaluationResult`.
* :mod:`.diagnostics` — :data:`DIAGNOSTICS`: the table of diagnostics (switch, accumulator, needs, report
  section, summary line); :mod:`.accumulators`: what the loop feeds them (:class:`BatchResult`).
* The standard IoU and the diagnostics, one module each: :mod:`.standard` (voxel IoU of the union of parts,
  metric found through ``cerberus.metrics``), :mod:`.hard` (the identity-conditional "Hard Human" test),
  :mod:`.part_quality` (the parts against the ground-truth semantic parts), :mod:`.visibility` (how often each
  part is hidden in its input view), :mod:`.depth` (depth across the views of a pose), :mod:`.segments` (per
  ground-truth body segment), :mod:`.allocation` (where the parts' keypoints go).
* :mod:`.masks` — :func:`~.masks.mask_iou`, the one mask IoU they (and :mod:`cerberus_core.photo_mask`) score with.
* :mod:`.report`, :mod:`.markdown` — JSON and Markdown.
* :mod:`.compare` — two evaluations compared image by image (:func:`paired_difference`).
* :mod:`.export` — GLB / OBJ files of posed parts; :mod:`.figures` — Figure 1 (b)-(f), Table 2, turntables;
  :mod:`.viewer` — the offline 3D viewer (also drawn by :mod:`cerberus_core.reconstruct`).

Reading user images, framing them and ``cerberus reconstruct``'s outputs are :mod:`cerberus_core.reconstruct`.
"""
