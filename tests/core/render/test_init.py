"""What importing the core costs: ``cerberus_core.render`` needs torch alone (no scipy, no trimesh)."""
from __future__ import annotations

import os
import subprocess
import sys
import textwrap

# A finder at the front of sys.meta_path that refuses the blocked packages, as if they were not
# installed; then import the render package and show what came in.
BLOCKED_IMPORT = textwrap.dedent("""
    import sys

    BLOCKED = {blocked!r}

    class Blocker:
        def find_spec(self, name, path=None, target=None):
            if name.split(".")[0] in BLOCKED:
                raise ImportError(f"{{name}} is blocked by the test")
            return None

    sys.meta_path.insert(0, Blocker())
    import cerberus_core.render
    from cerberus_core.render import Light, Renderer, RenderOutput, render, render_parts
    from cerberus_core.render.camera import Camera
    print(sorted(m for m in sys.modules if m.split(".")[0] in BLOCKED))
""")


def _run(code: str) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path))
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120)


def test_render_imports_without_scipy_or_trimesh() -> None:
    res = _run(BLOCKED_IMPORT.format(blocked=("scipy", "trimesh")))
    assert res.returncode == 0, res.stderr
    assert res.stdout.strip() == "[]"


def test_render_does_not_load_scipy_or_trimesh_when_installed() -> None:
    res = _run("import sys, cerberus_core.render\n"
               "print(sorted({m.split('.')[0] for m in sys.modules} & {'scipy', 'trimesh'}))")
    assert res.returncode == 0, res.stderr
    assert res.stdout.strip() == "[]"
