"""The plugin manager: built by a cached function (never at import) so tests can make fresh ones.

An installed plugin package that fails to import (or, in the registry, to register) is left out: every command
goes on without it after one warning line that names the package, its error and how to fix or uninstall it, and
``muble plugins`` lists it as broken. MuBlE's own plugins failing is an error (``PluginError``): MuBlE is not
whole then.
"""
from __future__ import annotations

import functools
import logging
import os
import warnings
from dataclasses import dataclass
from importlib import metadata

import pluggy

from muble.core.errors import MubleDeprecationWarning, PluginError
from muble.plugins import hookspecs

log = logging.getLogger(__name__)

ENTRY_POINT_GROUP = "muble"
DISABLE_AUTOLOAD_ENV = "MUBLE_DISABLE_PLUGIN_AUTOLOAD"
PLUGINS_ENV = "MUBLE_PLUGINS"  # comma-separated entry point names to load even when autoload is disabled
BUILTIN_DISTRIBUTION = "muble"


def _entry_points() -> list[metadata.EntryPoint]:
    return sorted(metadata.entry_points(group=ENTRY_POINT_GROUP), key=lambda ep: (ep.dist.name if ep.dist else "", ep.name))


def _wanted(ep: metadata.EntryPoint) -> bool:
    """Built-ins always load; external plugins unless autoload is disabled (then only those in MUBLE_PLUGINS)."""
    dist = ep.dist.name if ep.dist else ""
    if dist == BUILTIN_DISTRIBUTION:
        return True
    if os.environ.get(DISABLE_AUTOLOAD_ENV, "") not in ("", "0"):
        requested = {n.strip() for n in os.environ.get(PLUGINS_ENV, "").split(",") if n.strip()}
        return ep.name in requested
    return True


# Set in the environment to the packages already reported as broken (``dist:entry point``, comma-separated): the
# workers a command spawns inherit it and leave them out without saying so again.
REPORTED_ENV = "MUBLE_BROKEN_PLUGINS_REPORTED"


@dataclass(frozen=True)
class BrokenPlugin:
    """An installed plugin left out: its entry point failed to import, or one of its hooks raised or returned
    something other than records. ``stage`` says which (``"import"``, or the hook's name)."""

    name: str  # the entry point's name
    distribution: str  # the package that installed it (what ``pip uninstall`` takes)
    target: str  # the entry point's value, ``module`` or ``module:attribute``
    stage: str
    error: str  # ``"ImportError: No module named 'x'"``

    @property
    def fix(self) -> str:
        """What to do about it."""
        return (f"upgrade '{self.distribution}' to a release made for this MuBlE, or uninstall it: "
                f"pip uninstall {self.distribution}")

    @property
    def failure(self) -> str:
        """``"failed to import: ImportError: …"``, or in which hook it failed."""
        return ("failed to import" if self.stage == "import" else f"failed in {self.stage}") + f": {self.error}"

    def message(self) -> str:
        """The one line a command prints about it."""
        return (f"plugin package '{self.distribution}' left out: its entry point '{self.name}' ({self.target}) "
                f"{self.failure}. To fix: {self.fix} (or set {DISABLE_AUTOLOAD_ENV}=1 to load no installed plugin)")

    def report(self) -> None:
        """Log ``message()`` as a warning, once per run (the workers a command spawns stay quiet about it)."""
        key = f"{self.distribution}:{self.name}"
        reported = [k for k in os.environ.get(REPORTED_ENV, "").split(",") if k]
        if key in reported:
            log.debug("%s", self.message())
            return
        os.environ[REPORTED_ENV] = ",".join([*reported, key])
        log.warning("%s", self.message())


def describe_error(e: BaseException) -> str:
    """``"ImportError: No module named 'x'"``: the error's type and message, on one line."""
    return f"{type(e).__name__}: {' '.join(str(e).split())}" if str(e).strip() else type(e).__name__


class MublePluginManager(pluggy.PluginManager):
    """A pluggy manager that remembers which distribution provided each plugin, and which installed ones it left
    out (``broken``)."""

    def __init__(self) -> None:
        super().__init__(ENTRY_POINT_GROUP)
        self.distributions: dict[str, str] = {}
        self.targets: dict[str, str] = {}  # entry point name -> its value
        self.broken: list[BrokenPlugin] = []

    def distribution_of(self, plugin_name: str) -> str:
        return self.distributions.get(plugin_name, "(registered in code)")

    def is_installed(self, plugin_name: str) -> bool:
        """Whether the plugin came from an installed package other than MuBlE (an entry point): one that may be
        left out when it breaks."""
        return self.distributions.get(plugin_name, BUILTIN_DISTRIBUTION) != BUILTIN_DISTRIBUTION

    def leave_out(self, plugin_name: str, stage: str, error: BaseException) -> BrokenPlugin:
        """Unregister an installed plugin whose ``stage`` raised ``error``, and report it (``BrokenPlugin``)."""
        broken = BrokenPlugin(plugin_name, self.distribution_of(plugin_name), self.targets.get(plugin_name, "?"),
                              stage, describe_error(error))
        if self.has_plugin(plugin_name):
            self.unregister(name=plugin_name)
        self.broken.append(broken)
        broken.report()
        return broken


def _load(ep: metadata.EntryPoint, dist: str) -> object:
    """Import the entry point's plugin. A deprecated name it imports (``muble.plugins.deprecated``) is reported
    as one warning line naming the package, where the warning alone would name only a module."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", MubleDeprecationWarning)
        plugin = ep.load()
    for w in caught:
        if issubclass(w.category, MubleDeprecationWarning):
            log.warning("plugin package '%s' (entry point '%s', %s:%s): %s", dist, ep.name, w.filename, w.lineno,
                        w.message)
        else:  # anything else as it would have been shown
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno, source=w.source)
    return plugin


def _register(pm: MublePluginManager, plugin: object, name: str) -> None:
    """Register ``plugin``; a hook it implements that this MuBlE does not specify (misspelt, or from another
    release) fails here, not later in every command."""
    pm.register(plugin, name=name)
    unknown = sorted(caller.name for caller in pm.get_hookcallers(plugin) or [] if not caller.has_spec()
                     and any(i.plugin_name == name and not i.optionalhook for i in caller.get_hookimpls()))
    if unknown:
        hooks = sorted(n for n in dir(hookspecs) if n.startswith("muble_"))
        raise PluginError(f"it implements hooks this MuBlE does not have: {', '.join(unknown)} (its hooks: "
                          f"{', '.join(hooks)})")


def builtin_failed(name: str, target: str, stage: str, e: BaseException) -> PluginError:
    """The error for one of MuBlE's own plugins failing ``stage``: MuBlE's installation is not whole."""
    return PluginError(f"MuBlE's own plugin '{name}' ({target}) failed in {stage}: {describe_error(e)}. Reinstall "
                       "MuBlE (pip install --force-reinstall muble, or pip install -e . in a checkout)")


def make_plugin_manager(extra_plugins: tuple[object, ...] = ()) -> MublePluginManager:
    """A fresh plugin manager with every wanted entry point loaded, plus ``extra_plugins`` (modules or objects)."""
    pm = MublePluginManager()
    pm.add_hookspecs(hookspecs)
    for ep in _entry_points():
        if not _wanted(ep) or pm.has_plugin(ep.name):
            continue
        dist = ep.dist.name if ep.dist else "?"
        pm.distributions[ep.name], pm.targets[ep.name] = dist, ep.value
        stage = "import"
        try:
            plugin = _load(ep, dist)
            stage = "registration"
            _register(pm, plugin, ep.name)
        except Exception as e:  # noqa: BLE001 - whatever it raised, the plugin is named
            if not pm.is_installed(ep.name):
                raise builtin_failed(ep.name, ep.value, stage, e) from e
            pm.leave_out(ep.name, stage, e)
            continue
        log.debug("loaded plugin %s from %s", ep.name, dist)
    for i, plugin in enumerate(extra_plugins):
        pm.register(plugin, name=getattr(plugin, "__name__", f"extra-{i}"))
    pm.check_pending()
    return pm


@functools.cache
def get_plugin_manager() -> MublePluginManager:
    """The process-wide plugin manager (built on first use). ``get_plugin_manager.cache_clear()`` resets it."""
    return make_plugin_manager()
