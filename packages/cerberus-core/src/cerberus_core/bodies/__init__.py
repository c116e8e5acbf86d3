"""Where meshes come from: stateless body models, ``(subject, pose) -> posed mesh + part labels``.

The interface (:mod:`.sources`): a :class:`~cerberus_core.bodies.sources.BodySource` answers
``subjects(split, n, seed) -> [Subject]``, ``pose_pool(subject, split, n) -> [pose id]``,
``canonical_pose(subject) -> pose id | None``, ``motion_pairs(subject, split, n) -> [(id, id)]``
(human only) and ``bodies(subject, pose ids) -> [PosedBody]``,
each a pure function of its arguments and the source's options. A
:class:`~cerberus_core.bodies.sources.Subject` is a small JSON-ready record (``name`` + ``info``)
holding everything needed to pose it; the dataset manifest stores these records, so a reader
rebuilds any body from the manifest alone.

Modules, one line each:

* :mod:`.body` — the :class:`~cerberus_core.bodies.body.PosedBody` record and the normalisation rule;
* :mod:`.sources` — the ``BodySource`` interface, the ``Subject`` record, one adapter per source and
  :func:`~cerberus_core.bodies.sources.make_source`;
* :mod:`.human` — anny humans (phenotype sampling, joint-angle poses, posing and scale);
* :mod:`.human_motion` — everyday motion clips for human training pairs (two nearby frames each);
* :mod:`.animal` — procedural quadrupeds (species + pose -> watertight mesh), built from
  :mod:`.animal_shape` (species parameters), :mod:`.animal_pose` (pose sampling),
  :mod:`.animal_skeleton` (posed SDF primitives), :mod:`.animal_sdf` (distance fields) and
  :mod:`.animal_mesh` (marching cubes, decimation);
* :mod:`.primitives` — articulated capsule figures (fast, dependency-free; tests and smoke runs);
* :mod:`.folder` — your own posed meshes from a folder.

This package never imports :mod:`cerberus_core.datasets`; errors come from :mod:`cerberus_core.errors`.
"""
