"""Sub-commands of the ``cerberus`` CLI (one module each, see :mod:`cerberus_core.cli`)."""
