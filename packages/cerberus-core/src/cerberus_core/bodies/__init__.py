"""Where meshes come from: stateless body models, ``(subject, pose) -> posed mesh + part labels``.

* :mod:`.body` — the :class:`~cerberus_core.bodies.body.PosedBody` record and normalisation;
* :mod:`.human` (anny), :mod:`.animal` (procedural quadrupeds, with ``animal_*`` helpers),
  :mod:`.primitives` (capsule figures), :mod:`.folder` (your own meshes);
* :mod:`.sources` — the one interface the dataset generator and readers use.
"""
