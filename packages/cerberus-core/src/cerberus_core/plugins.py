"""Entry-point discovery of renderer backends, body sources and metrics (building a renderer by name is
:func:`cerberus_core.render.backends.make_renderer`).

Backends register under the ``cerberus.renderers`` group, body sources (the geometry a dataset is
rendered from: :class:`~cerberus_core.bodies.body.BodySource`) under ``cerberus.bodies``, metrics
under ``cerberus.metrics``, in the ``[project.entry-points]`` table of their package; the core's own
body sources register the same way (docs/bodies.md). Discovery uses the ``entrypoints`` package; core
never imports a backend, a body source or a metric package by name.

Failure modes are explicit:

* an unknown name → :class:`UnknownPluginError` naming the known ones and the package to install;
* a backend whose import fails → reported with its distribution and the error
  (:func:`plugin_table`), while the others keep working;
* one name registered by two distributions → :class:`DuplicatePluginError` naming both.
"""
from __future__ import annotations

import importlib.metadata
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import entrypoints

from cerberus_core.errors import DuplicatePluginError, PluginError, PluginLoadError, UnknownPluginError
from cerberus_core.plumbing.names import did_you_mean
from cerberus_core.release import VERSION

RENDERER_GROUP = "cerberus.renderers"
BODY_GROUP = "cerberus.bodies"
METRIC_GROUP = "cerberus.metrics"

#: What a plugin of each group is called in messages.
KINDS: dict[str, str] = {RENDERER_GROUP: "renderer", BODY_GROUP: "body source", METRIC_GROUP: "metric"}

#: Where the toolkit's own plugins live, for the "pip install ..." hint.
KNOWN_PACKAGES: dict[str, dict[str, str]] = {
    RENDERER_GROUP: {"torch": "cerberus-render-torch", "warp": "cerberus-render-warp"},
    METRIC_GROUP: {"voxel_iou": "cerberus-metrics", "chamfer_l2": "cerberus-metrics", "fscore": "cerberus-metrics",
                   "voxel_iou_scorer": "cerberus-metrics"},
}


@dataclass
class PluginInfo:
    """One discovered entry point.

    Attributes:
        name: the plugin name (``torch``, ``warp``, ``voxel_iou`` ...).
        group: the entry-point group.
        target: ``module:object`` the entry point refers to.
        distribution: the installed distribution that registers it.
        version: that distribution's version.
    """

    name: str
    group: str
    target: str
    distribution: str
    version: str
    _entry_point: Any = None

    def load(self) -> Any:
        """Import and return the registered object; :class:`PluginLoadError` if the import fails, however it
        fails (``SystemExit`` and ``GeneratorExit`` too: a plugin calling ``sys.exit`` at import made
        ``cerberus data generate`` exit 0 having done nothing; only Ctrl-C goes through)."""
        try:
            return self._entry_point.load()
        except KeyboardInterrupt:
            raise
        except BaseException as exc:  # noqa: BLE001 - any import-time failure is reported the same way
            raise PluginLoadError(
                f"{self.group} plugin '{self.name}' from {self.distribution} {self.version} ({self.target}) failed to load: "
                f"{type(exc).__name__}: {exc}. Reinstall it (pip install --force-reinstall {self.distribution}) "
                "or uninstall it to silence this."
            ) from exc


def discover(group: str, path: list[str] | None = None) -> dict[str, PluginInfo]:
    """All plugins of ``group`` on ``path`` (default ``sys.path``), by name.

    Raises:
        DuplicatePluginError: if two different distributions register one name.
    """
    found: dict[str, PluginInfo] = {}
    for ep in entrypoints.get_group_all(group, path=path):
        dist = (getattr(ep.distro, "name", None) or "<unknown distribution>").replace("_", "-")
        version = getattr(ep.distro, "version", None) or _installed_version(dist)
        target = f"{ep.module_name}:{ep.object_name}" if ep.object_name else ep.module_name
        info = PluginInfo(ep.name, group, target, dist, version, ep)
        # "?": metadata without a version, a source tree's NAME.egg-info that a wheel build leaves beside an editable
        # install's sources (found first when that folder leads sys.path, as under pytest): the toolkit itself
        if dist.lower() == "cerberus-core" and version not in (VERSION, "?"):
            raise DuplicatePluginError(
                f"{group} plugin '{ep.name}' comes from a distribution named cerberus-core {version} ({target}), "
                f"not this toolkit's cerberus-core {VERSION}: another package of that name shadows the toolkit's "
                "and would replace its plugins. Uninstall it (pip uninstall cerberus-core) and reinstall the "
                "toolkit from its wheelhouse (README, 'Installing with pip').")
        prev = found.get(ep.name)
        if prev is not None:
            if _same_dist(prev, info):
                if prev.version == "?":
                    found[ep.name] = info  # the installed metadata, with its version, over a source tree's
                continue  # the same distribution seen twice on sys.path
            raise DuplicatePluginError(
                f"{group} plugin name '{ep.name}' is registered by two packages: "
                f"{prev.distribution} {prev.version} ({prev.target}) and {dist} {version} ({target}). "
                f"Uninstall one of them (pip uninstall {dist})."
            )
        found[ep.name] = info
    return found


def _installed_version(dist: str) -> str:
    """The installed version of ``dist`` for an entry point whose metadata gave none (a source tree's
    ``NAME.egg-info``, whose folder name carries no version), ``"?"`` when it is not installed."""
    try:
        return importlib.metadata.version(dist)
    except importlib.metadata.PackageNotFoundError:
        return "?"


def _same_dist(a: PluginInfo, b: PluginInfo) -> bool:
    """Whether two entry points are one distribution seen twice on ``sys.path``: the same name, version (or one
    unknown: a source tree's egg-info) and target (issue 39: another version of a distribution named ``cerberus_core`` silently replaced a built-in
    source when only names were compared)."""
    norm = lambda s: s.lower().replace("_", "-")  # noqa: E731
    versions = a.version == b.version or "?" in (a.version, b.version)  # "?": a source tree's egg-info of it
    return versions and (norm(a.distribution), a.target) == (norm(b.distribution), b.target)


def plugin_origin(group: str, name: str) -> str:
    """``'NAME' (DISTRIBUTION VERSION, TARGET)``: where the plugin ``name`` of ``group`` comes from, for a
    message about something it broke (``'NAME'`` alone when it is not registered)."""
    try:
        info = discover(group).get(name)
    except PluginError:
        info = None
    return f"'{name}'" if info is None else f"'{name}' ({info.distribution} {info.version}, {info.target})"


def _install_hint(group: str, name: str) -> str:
    pkg = KNOWN_PACKAGES.get(group, {}).get(name)
    if pkg:
        return f"install it with `pip install {pkg}` (from the toolkit's wheelhouse: README, 'Installing with pip')"
    return "install the package that provides it"


def get_plugin(group: str, name: str, path: list[str] | None = None) -> Any:
    """Load the plugin ``name`` of ``group``.

    Raises:
        UnknownPluginError: naming the installed plugins and the package to install.
        PluginLoadError: if it is installed but fails to import.
    """
    plugins = discover(group, path)
    if name not in plugins:
        known = ", ".join(sorted(plugins)) or "none"
        kind = KINDS.get(group, "plugin")
        hint = did_you_mean(name, sorted(plugins))
        fix = "" if hint else f" To use '{name}', {_install_hint(group, name)}."
        raise UnknownPluginError(f"unknown {kind} '{name}'{hint} (group {group}); installed: {known}.{fix}")
    return plugins[name].load()


def plugin_table(group: str, path: list[str] | None = None) -> list[dict[str, str]]:
    """One row per discovered plugin with its status: ``ok`` or the load error."""
    rows = []
    for name, info in sorted(discover(group, path).items()):
        try:
            info.load()
            status = "ok"
        except PluginLoadError as exc:
            status = f"error: {exc.__cause__!r}"
        rows.append({"name": name, "package": info.distribution, "version": info.version,
                     "target": info.target, "status": status})
    return rows


def plugin_names(group: str, path: list[str] | None = None) -> list[str]:
    """The names registered under ``group``, sorted (nothing is imported)."""
    return sorted(discover(group, path))


def get_metric(name: str) -> Callable[..., Any]:
    """Load a metric callable registered under ``cerberus.metrics`` (e.g. ``voxel_iou``)."""
    return get_plugin(METRIC_GROUP, name)
