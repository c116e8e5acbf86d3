"""Entry-point discovery of renderers and metrics (cerberus_core.plugins) and its failure modes."""
from __future__ import annotations

import sys

import pytest

from cerberus_core.errors import CerberusError, DuplicatePluginError, PluginError, PluginLoadError, UnknownPluginError
from cerberus_core.plugins import METRIC_GROUP, RENDERER_GROUP, discover, get_plugin, plugin_table
from cerberus_core.render.backends import available_renderers, make_renderer
from cerberus_core.render.interface import Renderer
from tests.support.dists import BROKEN, WORKING


def test_the_torch_backend_is_discovered_with_its_package() -> None:
    found = discover(RENDERER_GROUP)
    assert found["torch"].distribution == "cerberus-render-torch"
    assert found["torch"].target == "cerberus_render_torch:TorchRenderer"
    assert "torch" in available_renderers()
    renderer = make_renderer("torch")
    assert isinstance(renderer, Renderer) and renderer.name == "torch"


def test_every_registered_renderer_imports() -> None:
    broken = [row for row in plugin_table(RENDERER_GROUP) if row["status"] != "ok"]
    assert not broken, f"installed renderer backends fail to import: {broken}"


def test_unknown_name_lists_the_installed_ones_and_the_package_to_install(tmp_path) -> None:
    with pytest.raises(UnknownPluginError) as err:
        make_renderer("no-such-backend")
    assert "no-such-backend" in str(err.value) and "torch" in str(err.value)
    assert isinstance(err.value, KeyError)
    # A known toolkit backend that is not installed (empty path) names its package.
    with pytest.raises(UnknownPluginError, match=r"installed: none.*pip install cerberus-render-warp"):
        get_plugin(RENDERER_GROUP, "warp", path=[str(tmp_path)])
    with pytest.raises(UnknownPluginError, match=r"pip install cerberus-metrics"):
        get_plugin(METRIC_GROUP, "voxel_iou", path=[str(tmp_path)])


def test_a_backend_that_fails_to_import_is_reported_while_others_work(fake_dist, monkeypatch) -> None:
    root = fake_dist("fake-broken-render", {RENDERER_GROUP: {"broken": "fake_broken_backend:Renderer"}}, BROKEN)
    fake_dist("fake-good-render", {RENDERER_GROUP: {"good": "fake_good_backend:GoodRenderer"}}, WORKING)
    monkeypatch.syspath_prepend(str(root))
    rows = {r["name"]: r for r in plugin_table(RENDERER_GROUP, path=[str(root)])}
    assert rows["broken"]["package"] == "fake-broken-render" and rows["broken"]["version"] == "0.1"
    assert rows["broken"]["status"].startswith("error:") and "libfake.so" in rows["broken"]["status"]
    assert rows["good"]["status"] == "ok"
    assert available_renderers(path=[str(root)]) == ["good"]
    with pytest.raises(PluginLoadError, match=r"fake-broken-render 0.1 .*ImportError: libfake.so"):
        get_plugin(RENDERER_GROUP, "broken", path=[str(root)])
    # On the real sys.path the broken plugin sits beside the installed backends, which keep working.
    assert "broken" not in available_renderers() and "torch" in available_renderers()
    assert make_renderer("torch").name == "torch"
    with pytest.raises(PluginLoadError, match="fake-broken-render"):
        make_renderer("broken")
    sys.modules.pop("fake_good_backend", None)


def test_two_packages_registering_one_name_is_an_error_naming_both(fake_dist, monkeypatch) -> None:
    root = fake_dist("fake-render-a", {RENDERER_GROUP: {"twin": "fake_a:Renderer"}})
    fake_dist("fake-render-b", {RENDERER_GROUP: {"twin": "fake_b:Renderer"}})
    with pytest.raises(DuplicatePluginError, match="'twin'") as err:
        discover(RENDERER_GROUP, path=[str(root)])
    assert "fake-render-a" in str(err.value) and "fake-render-b" in str(err.value)
    # Shadowing an installed backend's name is caught the same way by make_renderer.
    clone = fake_dist("fake-torch-clone", {RENDERER_GROUP: {"torch": "fake_clone:Renderer"}}, folder="other")
    monkeypatch.syspath_prepend(str(clone))
    with pytest.raises(DuplicatePluginError, match="'torch'") as err:
        make_renderer("torch")
    assert "fake-torch-clone" in str(err.value) and "cerberus-render-torch" in str(err.value)


def test_a_plugin_that_is_not_a_renderer_is_rejected(fake_dist, monkeypatch) -> None:
    root = fake_dist("fake-not-renderer", {RENDERER_GROUP: {"notone": "fake_not_renderer:Thing"}},
                     {"fake_not_renderer": "class Thing:\n    pass\n"})
    monkeypatch.syspath_prepend(str(root))
    with pytest.raises(PluginLoadError, match="not a cerberus_core Renderer"):
        make_renderer("notone")
    sys.modules.pop("fake_not_renderer", None)


def test_plugin_errors_are_cerberus_errors() -> None:
    """One base class: ``except CerberusError`` (the ``cerberus`` command) catches plugin errors too,
    and callers that caught them as ``RuntimeError`` (or an unknown name as ``KeyError``) still do."""
    for cls in (PluginError, UnknownPluginError, DuplicatePluginError, PluginLoadError):
        assert issubclass(cls, CerberusError) and issubclass(cls, RuntimeError)
    assert issubclass(UnknownPluginError, KeyError)
    with pytest.raises(CerberusError, match="unknown"):
        get_plugin(RENDERER_GROUP, "no_such_backend")
