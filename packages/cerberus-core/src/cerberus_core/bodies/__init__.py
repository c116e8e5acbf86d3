"""Where meshes come from: stateless body models, ``(subject, pose) -> posed mesh + part labels``.

The interface (:mod:`.body`): a :class:`~cerberus_core.bodies.body.BodySource` answers
``subjects(split, n, seed) -> [Subject]``, ``pose_pool(subject, split, n) -> [pose id]``,
``canonical_pose(subject) -> pose id | None``, ``motion_pairs(subject, split, n) -> [(id, id)]``
(human only) and ``bodies(subject, pose ids) -> [PosedBody]``,
each a pure function of its arguments and the source's options. A
:class:`~cerberus_core.bodies.body.Subject` is a small JSON-ready record (``name`` + ``info``)
holding everything needed to pose it; the dataset manifest stores these records, so a reader
rebuilds any body from the manifest alone. Sources are found by name through the ``cerberus.bodies``
entry points (:func:`~cerberus_core.bodies.body.source_class`), the core's own included.

Modules, one line each:

* :mod:`.body` — the ``BodySource`` contract, the ``Subject`` and :class:`~cerberus_core.bodies.body.PosedBody`
  records, the normalisation rule and :func:`~cerberus_core.bodies.body.source_class`;
* :mod:`.sources` — the ``human``, ``animal`` and ``primitives`` sources (adapters over the modules below);
* :mod:`.human` — anny humans (phenotype sampling, joint-angle poses, posing and scale);
* :mod:`.human_motion` — everyday motion clips for human training pairs (two nearby frames each);
* :mod:`.animal` — procedural quadrupeds (species + pose -> watertight mesh), built from
  :mod:`.animal_shape` (species parameters), :mod:`.animal_pose` (pose sampling),
  :mod:`.animal_skeleton` (posed SDF primitives), :mod:`.animal_sdf` (distance fields) and
  :mod:`.animal_mesh` (marching cubes, decimation);
* :mod:`.primitives` — articulated capsule figures (fast, dependency-free; tests and smoke runs);
* :mod:`.folder` — the ``folder`` source: your own posed meshes from a folder.

This package never imports :mod:`cerberus_core.datasets`; errors come from :mod:`cerberus_core.errors`.
"""
