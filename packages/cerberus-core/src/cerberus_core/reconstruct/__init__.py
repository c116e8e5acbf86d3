"""Reconstruction of image files with a trained model: what ``cerberus reconstruct`` does
(:meth:`cerberus_core.run.Run.reconstruct_images`, the one way in; docs/evaluation.md, "Using a trained model").

* :mod:`.images` — reading user images (alpha, size, bit depth, orientation, unreadable files).
* :mod:`.input_domain` — silhouettes (alpha or a mask), framing like the training images, and the checks that
  name an input outside the training domain (background, framing, colour and texture of the body).
* :mod:`.fit` — :func:`~cerberus_core.reconstruct.fit.fit_silhouette`: a reconstruction fitted to its silhouette
  after the network's prediction (``cerberus reconstruct --fit``).
* :mod:`.write` — :func:`~cerberus_core.reconstruct.write.write_reconstructions`: meshes, Figure 1's pictures
  and the 3D viewer of each image, in one result folder.

It draws with :mod:`cerberus_core.eval`'s outputs (figures, export, viewer); ``eval/`` imports nothing of it.
"""
