"""The ``warp`` backend as users meet it: entry point, render_parts parity, errors, quiet start-up."""
from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import pytest
import torch

from cerberus_core import Light, available_renderers, make_renderer, render_parts
from cerberus_render_warp import WarpRenderer
from tests.support.scenes import part_scene


def test_found_through_the_entry_point(warp_renderer) -> None:
    assert "warp" in available_renderers()
    assert isinstance(warp_renderer, WarpRenderer) and warp_renderer.name == "warp"
    with pytest.raises(TypeError, match="unknown options"):
        make_renderer("warp", tile_size=8)


@pytest.mark.parametrize("fused_shading", [True, False])
def test_render_parts_matches_torch_backend(fused_shading: bool) -> None:
    parts, faces, cam = part_scene(4, 9, (48, 40), seed=11)
    albedo = torch.rand(4, 9, 3, generator=torch.Generator().manual_seed(0))
    outs, grads = [], []
    for r in (make_renderer("torch"), make_renderer("warp", fused_shading=fused_shading)):
        p = parts.clone().requires_grad_(True)
        out = render_parts(r, p, faces, cam, Light.following(cam), albedo=albedo, background=(0.1, 0.2, 0.3))
        (out.image.square().sum() + out.depth.sum()).backward()
        outs.append(out)
        grads.append(p.grad)
    ref, ours = outs
    assert torch.equal(ours.face_id, ref.face_id) and torch.equal(ours.part_id, ref.part_id)
    assert torch.equal(ours.alpha, ref.alpha)
    assert (ours.image - ref.image).abs().max() < 1e-5 and (ours.depth - ref.depth).abs().max() < 1e-5
    assert ((grads[1] - grads[0]).abs().max() / grads[0].abs().max()) < 1e-4


def test_kernels_are_not_rebuilt_per_call(warp_renderer) -> None:
    import warp as wp

    def loaded() -> dict[str, int]:
        mods = ("cerberus_render_warp.rasterize", "cerberus_render_warp.shade")
        return {m: sum(map(id, wp.get_module(m).execs.values())) for m in mods}

    for size, batch in ((16, 1), (24, 3)):
        parts, faces, cam = part_scene(batch, 2, size, seed=size)
        parts.requires_grad_(True)
        render_parts(warp_renderer, parts, faces, cam).image.sum().backward()
        if size == 16:
            before = loaded()
    assert loaded() == before


def _python(code: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONWARNINGS": "ignore"}
    return subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True, text=True, env=env,
                          timeout=300)


def test_rendering_prints_nothing() -> None:
    res = _python("""
        import torch
        from cerberus_core import Camera, icosphere, make_renderer, render_parts
        cam = Camera.look_at(30.0, 10.0, 2.5, image_size=16)
        parts = 0.2 * icosphere(2).vertices.expand(1, 1, -1, -1)
        out = render_parts(make_renderer("warp"), parts.clone().requires_grad_(True), icosphere(2).faces, cam)
        out.image.sum().backward()
        assert out.alpha.sum() > 0
    """)
    assert res.returncode == 0, res.stderr
    assert res.stdout == "" and res.stderr == ""


def test_missing_warp_names_the_package() -> None:
    res = _python("""
        import sys
        sys.modules["warp"] = None  # as if warp-lang were not installed
        from cerberus_core import make_renderer
        try:
            make_renderer("warp")
        except Exception as exc:
            print(type(exc).__name__, exc)
    """)
    assert res.returncode == 0, res.stderr
    assert "PluginLoadError" in res.stdout and "pip install 'warp-lang" in res.stdout



def test_the_first_compile_is_announced_before_it_starts(tmp_path, monkeypatch, capsys):
    """Issue 34: with an empty kernel cache the backend says it compiles, and about how long that takes (4-8 s
    measured here, half a minute in the issue's report, silent otherwise); with its kernels cached it says nothing."""
    import warp as wp

    from cerberus_render_warp.quiet import announce_first_compile

    monkeypatch.setattr(wp.config, "kernel_cache_dir", str(tmp_path))
    announce_first_compile()
    said = capsys.readouterr().err
    assert f"compiling the Warp renderer's kernels into {tmp_path}" in said and "about 5 s" in said
    (tmp_path / "wp_cerberus_render_warp.rasterize_0123abc").mkdir()
    announce_first_compile()
    assert capsys.readouterr().err == ""
