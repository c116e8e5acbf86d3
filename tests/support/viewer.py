"""Reading the 3D viewer's page (cerberus_core.eval.viewer) in tests: its embedded data, without a browser."""
from __future__ import annotations

import json
import re
from pathlib import Path


def page_data(page: Path) -> dict:
    """The JSON the page embeds for its script (``#cerberus-viewer-data``): entries, part labels, lights."""
    m = re.search(r'<script type="application/json" id="cerberus-viewer-data">(.*?)</script>', page.read_text(), re.S)
    assert m, f"{page} embeds no viewer data"
    return json.loads(m.group(1))
