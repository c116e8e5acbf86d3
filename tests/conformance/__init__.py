"""Renderer conformance suite: every discovered backend against the contract of
``cerberus_core.render.interface``, an independent numpy reference, analytic scenes and each other.
See README.md in this folder for running it against a third-party backend."""
