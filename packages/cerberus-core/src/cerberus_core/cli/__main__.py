"""``python -m cerberus_core.cli`` (used with ``torchrun``): the ``cerberus`` command."""
import sys

from cerberus_core.cli import main

sys.exit(main())
