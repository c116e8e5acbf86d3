"""Datasets: body sources, scene set-up, generation, the on-disk format and torch readers.

* bodies: :mod:`.body` (the ``PosedBody`` record), :mod:`.human` (anny), :mod:`.animal`
  (procedural quadrupeds), :mod:`.primitives` (capsule figures), :mod:`.folder` (your meshes),
  behind one interface in :mod:`.sources`;
* :mod:`.scene` (cameras and light of a view), :mod:`.plan` (presets and the deterministic shard
  plan), :mod:`.generate` (the resumable driver), :mod:`.format` (manifest, shards, checksums);
* :mod:`.dataset` (``QuadrupletDataset``, ``ViewDataset``, ``ShardStream``), :mod:`.show`
  (contact sheets).

The format is documented in ``docs/data_format.md``.
"""
