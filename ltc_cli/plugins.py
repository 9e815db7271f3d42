"""The plugin manager: loads every ``ltc`` entry point (built-ins included) and keeps the registries."""

from __future__ import annotations

import importlib
import os
from dataclasses import dataclass
from typing import Any, Callable

import pluggy

from ltc_cli import hookspecs
from ltc_cli.errors import PluginError

KINDS = ("detectors", "metrics", "policies", "readers")


@dataclass(frozen=True)
class Registered:
    name: str
    factory: Any
    plugin: str


_pm: pluggy.PluginManager | None = None
_registries: dict[str, dict[str, Registered]] | None = None


def get_plugin_manager() -> pluggy.PluginManager:
    global _pm
    if _pm is None:
        pm = pluggy.PluginManager("ltc")
        pm.add_hookspecs(hookspecs)
        pm.load_setuptools_entrypoints("ltc")
        # Extra plugin modules by import name, for trying a plugin without packaging it.
        for name in filter(None, (m.strip() for m in os.environ.get("LTC_PLUGINS", "").split(","))):
            if pm.get_plugin(name) is None:
                try:
                    pm.register(importlib.import_module(name), name=name)
                except ImportError as exc:
                    raise PluginError(f"cannot import plugin module {name!r} named in LTC_PLUGINS ({exc})") from None
        # A plugin that implements a hook we do not specify is a typo or a version skew: say so now.
        pm.check_pending()
        _pm = pm
    return _pm


def _collect(kind: str) -> dict[str, Registered]:
    pm = get_plugin_manager()
    found: dict[str, Registered] = {}
    hook = getattr(pm.hook, f"register_{kind}")
    for impl in hook.get_hookimpls():
        plugin_name = pm.get_name(impl.plugin) or repr(impl.plugin)

        def register(name: str, factory: Callable, _plugin=plugin_name) -> None:
            if name in found:
                raise PluginError(
                    f"{kind[:-1]} {name!r} is registered twice (by {found[name].plugin} and {_plugin})"
                )
            found[name] = Registered(name, factory, _plugin)

        impl.function(register=register)
    return found


def registry(kind: str) -> dict[str, Registered]:
    global _registries
    if _registries is None:
        _registries = {k: _collect(k) for k in KINDS}
    return _registries[kind]


def get(kind: str, name: str) -> Registered:
    reg = registry(kind)
    if name not in reg:
        known = ", ".join(sorted(reg)) or "none installed"
        raise PluginError(f"unknown {kind[:-1]} {name!r} (installed: {known})")
    return reg[name]


def reset() -> None:
    """Forget loaded plugins (tests register extra ones and then reload)."""
    global _pm, _registries
    _pm = None
    _registries = None


def register_plugin(module: Any, name: str | None = None) -> None:
    """Register a plugin object by hand (tests, embedding applications)."""
    global _registries
    get_plugin_manager().register(module, name=name)
    _registries = None


def unregister_plugin(name: str) -> None:
    global _registries
    get_plugin_manager().unregister(name=name)
    _registries = None


def describe() -> list[dict]:
    """What ``ltc plugins`` shows: every plugin with its hooks and the names it registers."""
    pm = get_plugin_manager()
    rows = []
    for plugin_name, plugin in sorted(pm.list_name_plugin(), key=lambda t: t[0]):
        hooks = sorted(h.name for h in pm.get_hookcallers(plugin) or [])
        names = {
            kind: sorted(r.name for r in registry(kind).values() if r.plugin == plugin_name)
            for kind in KINDS
        }
        dist = None
        for p, d in pm.list_plugin_distinfo():
            if p is plugin:
                dist = f"{d.project_name} {d.version}"
        rows.append({"name": plugin_name, "hooks": hooks, "registers": names, "package": dist})
    return rows


__all__ = ["get_plugin_manager", "registry", "get", "describe", "register_plugin", "KINDS"]
