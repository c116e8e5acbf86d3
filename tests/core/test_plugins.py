"""Entry-point discovery of renderers and metrics (cerberus_core.plugins) and its failure modes."""
from __future__ import annotations

import sys

import pytest

from cerberus_core.bodies.body import source_class
from cerberus_core.errors import (
    BodyError,
    CerberusError,
    ConfigError,
    DuplicatePluginError,
    PluginError,
    PluginLoadError,
    UnknownPluginError,
)
from cerberus_core.plugins import BODY_GROUP, METRIC_GROUP, RENDERER_GROUP, discover, get_plugin, plugin_table
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


SOURCE = """
from dataclasses import dataclass
from cerberus_core.bodies.sources import PrimitiveSource

class Blocks(PrimitiveSource):
    name = "{name}"
"""


@pytest.mark.parametrize("body", ["raise SystemExit(0)", "raise GeneratorExit()", "raise BaseException('odd')"])
def test_a_plugin_whose_import_exits_is_one_load_error_naming_it(fake_dist, monkeypatch, body) -> None:
    """Issue 39: ``sys.exit`` at a plugin's import made ``cerberus data generate`` exit 0 having done nothing."""
    root = fake_dist("fake-exit", {BODY_GROUP: {"exits": "fake_exit_source:Source"}}, {"fake_exit_source": body})
    monkeypatch.syspath_prepend(str(root))
    with pytest.raises(PluginLoadError, match=r"plugin 'exits' from fake-exit 0.1 \(fake_exit_source:Source\) failed"):
        source_class("exits")
    sys.modules.pop("fake_exit_source", None)


def test_a_source_is_known_by_one_name_and_options_are_a_dataclass(fake_dist, monkeypatch) -> None:
    """Issue 39: an entry point ``fakeblocks`` whose class said ``name = "human"`` labelled a dataset with both names;
    ``Options = dict`` was a traceback at run time."""
    modules = {"fake_blocks": SOURCE.format(name="human"),
               "fake_opts": SOURCE.format(name="badopts") + "    Options = dict\n"}
    root = fake_dist("fake-blocks", {BODY_GROUP: {"fakeblocks": "fake_blocks:Blocks", "badopts": "fake_opts:Blocks"}},
                     modules)
    monkeypatch.syspath_prepend(str(root))
    with pytest.raises(ConfigError, match=r"entry point 'fakeblocks' \(fake-blocks 0.1, fake_blocks:Blocks\) holds a "
                       r"source whose `name` is 'human'; a source has one name"):
        source_class("fakeblocks")
    with pytest.raises(ConfigError, match=r"'badopts' \(fake-blocks 0.1, fake_opts:Blocks\) has `Options` <class "
                       r"'dict'>, not a dataclass"):
        source_class("badopts")
    for name in ("fake_blocks", "fake_opts"):
        sys.modules.pop(name, None)


def test_another_version_of_a_distribution_never_replaces_a_source(fake_dist, monkeypatch) -> None:
    """Issue 39: a distribution named ``cerberus_core`` (another version) silently replaced the built-in ``human``
    source, since only names were compared."""
    root = fake_dist("cerberus_core", {BODY_GROUP: {"human": "fake_human:Blocks"}},
                     {"fake_human": SOURCE.format(name="human")})
    monkeypatch.syspath_prepend(str(root))
    with pytest.raises(DuplicatePluginError, match=r"plugin 'human' comes from a distribution named cerberus-core 0.1 "
                       r"\(fake_human:Blocks\), not this toolkit's cerberus-core 0.2.0\+toolkit"):
        source_class("human")
    sys.modules.pop("fake_human", None)


def test_a_source_trees_egg_info_without_a_version_is_the_toolkit_itself(tmp_path, monkeypatch) -> None:
    """A wheel build leaves ``src/cerberus_core.egg-info`` (no version in its folder name) beside an editable install's
    sources; under pytest that folder leads sys.path, so the entry points were read from it first and the check above
    took it for another distribution of the name (the whole suite failed on a clean clone after the install check)."""
    from cerberus_core.plugins import discover
    egg = tmp_path / "src" / "cerberus_core.egg-info"
    egg.mkdir(parents=True)
    (egg / "PKG-INFO").write_text("Metadata-Version: 2.1\nName: cerberus-core\nVersion: 0.2.0+toolkit\n")
    (egg / "entry_points.txt").write_text("[cerberus.bodies]\nhuman = cerberus_core.bodies.sources:HumanSource\n")
    found = discover(BODY_GROUP, path=[str(tmp_path / "src"), *sys.path])
    assert found["human"].version == "0.2.0+toolkit" and found["human"].target == "cerberus_core.bodies.sources:HumanSource"


def test_what_a_source_breaks_at_run_time_names_it(fake_dist, monkeypatch, tmp_path) -> None:
    """Issue 39: a Subject.info JSON cannot hold, or an exception inside bodies(), was a traceback naming no plugin."""
    from dataclasses import replace

    from cerberus_core.datasets.dataset import Dataset
    from cerberus_core.datasets.plan import preset_config

    info = SOURCE.format(name="badinfo") + (
        "    def subjects(self, split, n, seed):\n"
        "        return [type(s)(s.name, {**s.info, 'when': object()}) for s in super().subjects(split, n, seed)]\n")
    boom = SOURCE.format(name="boom") + "    def bodies(self, subject, poses):\n        raise ZeroDivisionError('x')\n"
    root = fake_dist("fake-bad", {BODY_GROUP: {"badinfo": "fake_info:Blocks", "boom": "fake_boom:Blocks"}},
                     {"fake_info": info, "fake_boom": boom})
    monkeypatch.syspath_prepend(str(root))
    with pytest.raises(BodyError, match=r"^the body source 'badinfo' \(fake-bad 0.1, fake_info:Blocks\) failed in the "
                       r"info of subject .*TypeError: Object of type object is not JSON serializable"):
        Dataset.plan(replace(preset_config("primitives", "tiny"), dataset="badinfo"), tmp_path / "a")
    with pytest.raises(BodyError, match=r"^the body source 'boom' \(fake-bad 0.1, fake_boom:Blocks\) failed in "
                       r"bodies\(\) of subject .*: ZeroDivisionError: x; fix the source or uninstall it"):
        Dataset.generate(replace(preset_config("primitives", "tiny"), dataset="boom"), tmp_path / "b", progress=False,
                         log=lambda s: None)
    assert not (tmp_path / "a").exists()
    for name in ("fake_info", "fake_boom"):
        sys.modules.pop(name, None)
