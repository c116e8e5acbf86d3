"""Datasets: plan, generate, store and read rendered quadruplets (bodies come from :mod:`cerberus_core.bodies`).

Modules, one line each:

* :mod:`.scene` — :class:`~cerberus_core.datasets.scene.SceneSetup`, the one owner of a dataset's
  scene: cameras (from azimuths or stored view records), light, background; round-trips the manifest;
* :mod:`.plan` — generation configs (YAML size presets in ``configs/data/``, ``--set``) and the
  deterministic shard plan;
* :mod:`.generate` — the resumable, deterministic driver: plan → pose → render → atomic shards → manifest;
* :mod:`.manifest` — the typed manifest (:class:`~cerberus_core.datasets.manifest.Manifest` and its
  split, shard, file, subject and source records), read and written both ways;
* :mod:`.format` — the on-disk format: shard files, checksums, atomic writes, verification;
* :mod:`.readers` — torch datasets: ``QuadrupletDataset`` (training), ``ViewDataset`` (evaluation,
  ground-truth meshes rebuilt from the manifest's subject records when not stored);
* :mod:`.show` — contact sheets of a split.

The format is documented in ``docs/data_format.md``.
"""
