"""The renderer conformance suite: what every Cerberus renderer backend is held to, shipped with the core.

Any backend registered under the ``cerberus.renderers`` entry-point group is checked against the contract
written in :mod:`cerberus_core.render.interface` (the rasterization rule, shading, depths, gradients,
anti-aliasing, edge cases), against an independent numpy renderer (:mod:`.reference`) and, where
``cerberus-render-torch`` is installed, against that reference backend. It needs pytest
(``pip install "cerberus-core[testing]"``) and runs from the installed package, no clone needed::

    python -m cerberus_core.testing --renderer mybackend        # one backend (repeatable)
    python -m cerberus_core.testing                             # every installed backend
    python -m cerberus_core.testing --renderer warp -k contract # any pytest option after the name

docs/backends.md is the backend author's guide: the interface, the contract, the entry point and a
worked minimal backend.
"""
