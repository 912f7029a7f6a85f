"""The registry: every plugin record by kind and name, gathered once from the plugin manager."""
from __future__ import annotations

import functools
from typing import Any, cast

from omegaconf import DictConfig, OmegaConf

from muble.core.errors import PluginError, unknown_name
from muble.core.physical_properties import Property, use_loader
from muble.core.ranges import checked_node, configured
from muble.plugins.manager import BUILTIN_DISTRIBUTION, BrokenPlugin, MublePluginManager, builtin_failed, get_plugin_manager
from muble.plugins.records import KINDS, PluginRecord, Provided


class Registry:
    """Plugin records by kind and name. Two providers of one name are an error naming both.

    An installed plugin whose registration hook raises, or returns something other than ``PluginRecord``s, is
    left out with all it registered (``broken`` lists it beside those that failed to import); one of MuBlE's own
    plugins failing so is a ``PluginError``.
    """

    def __init__(self, pm: MublePluginManager, kinds: tuple[str, ...] | None = None):
        """``kinds`` limits what is gathered (``("property",)``: the hidden properties alone, which templates need
        while they compile, before the registry of everything is there); None: every kind."""
        self.pm = pm
        self._by_kind: dict[str, dict[str, Provided]] = {}
        gathered: list[Provided] = []
        # The hidden properties first: other plugins read them while they register (a template file compiles its
        # property words and steps), through ``muble.core.physical_properties.registered``.
        self.properties: dict[str, Property] = {}
        global _building
        outer, _building = _building, self
        try:
            for kind in ("property", *(k for k in KINDS if k != "property" and (kinds is None or k in kinds))):
                gathered += self._gather(kind)
                if kind == "property":
                    self.properties = self._properties(gathered)
        finally:
            _building = outer
        self._index(gathered)

    def _gather(self, kind: str) -> list[Provided]:
        """Every record the plugins register as ``kind`` (a broken plugin's left out and reported)."""
        pm, hook_name, gathered = self.pm, KINDS[kind], []
        for impl in getattr(pm.hook, hook_name).get_hookimpls():
            try:
                records = [_property_record(r) if kind == "property" else r for r in impl.function() or []]
                for record in records:
                    if not isinstance(record, PluginRecord):
                        raise PluginError(
                            f"plugin '{impl.plugin_name}' returned {type(record).__name__} from {hook_name}; "
                            "registration hooks must return a list of muble.PluginRecord")
            except Exception as e:  # noqa: BLE001 - whatever a plugin's hook raises, the plugin is named
                self._failed(impl.plugin_name, hook_name, e)
                continue
            gathered += [Provided(kind, r, impl.plugin_name, pm.distribution_of(impl.plugin_name))
                         for r in records]
        return gathered

    def _properties(self, gathered: list[Provided]) -> dict[str, Property]:
        """The registered properties by name: MuBlE's own first in their order, then each other package's in its
        order. Two of one name are an error naming both providers."""
        left_out = {b.name for b in self.pm.broken}
        props = [p for p in gathered if p.kind == "property" and p.plugin not in left_out]
        own = [p for p in props if self.pm.distributions.get(p.plugin) == BUILTIN_DISTRIBUTION]
        out: dict[str, Property] = {}
        for p in [*own, *(p for p in props if p not in own)]:
            out.setdefault(p.record.name, p.record.factory())
        return out

    def _index(self, gathered: list[Provided]) -> None:
        pm = self.pm
        # The config folders, from the plugins still registered (a broken one's are not wanted), in the order a
        # hook call gives them (the last registered first).
        self.searchpath: list[str] = []
        for impl in reversed(pm.hook.muble_config_searchpath.get_hookimpls()):
            try:
                self.searchpath += [str(p) for p in cast("list[str] | None", impl.function()) or []]
            except Exception as e:  # noqa: BLE001 - as above
                self._failed(impl.plugin_name, "muble_config_searchpath", e)
        left_out = {b.name for b in pm.broken}
        for kind in KINDS:
            providers: dict[str, list[Provided]] = {}
            for p in gathered:
                if p.kind == kind and p.plugin not in left_out:
                    providers.setdefault(p.record.name, []).append(p)
            clashes = {n: ps for n, ps in providers.items() if len(ps) > 1}
            if clashes:
                lines = [
                    f"{kind} '{n}' is provided by " + " and ".join(f"plugin '{p.plugin}' ({p.distribution})" for p in ps)
                    for n, ps in sorted(clashes.items())
                ]
                raise PluginError("duplicate plugin names: " + "; ".join(lines) + ". Rename one or uninstall it.")
            self._by_kind[kind] = {n: ps[0] for n, ps in providers.items()}


    @property
    def broken(self) -> list[BrokenPlugin]:
        """The installed plugins left out: failed to import or to register (``muble plugins`` lists them)."""
        return list(self.pm.broken)

    def _failed(self, plugin: str, hook_name: str, e: Exception) -> None:
        """An installed plugin's hook failed: leave the plugin out. A plugin registered in code raises as it
        did; one of MuBlE's own as a ``PluginError`` naming it."""
        if plugin not in self.pm.distributions:
            raise e
        if not self.pm.is_installed(plugin):
            raise builtin_failed(plugin, self.pm.targets[plugin], hook_name, e) from e
        self.pm.leave_out(plugin, hook_name, e)

    def _check_kind(self, kind: str) -> None:
        if kind not in self._by_kind:
            raise PluginError(unknown_name("plugin kind", kind, list(KINDS)))

    def names(self, kind: str) -> list[str]:
        self._check_kind(kind)
        return sorted(self._by_kind[kind])

    def get(self, kind: str, name: str) -> Provided:
        self._check_kind(kind)
        try:
            return self._by_kind[kind][name]
        except KeyError:
            raise PluginError(unknown_name(kind, name, self.names(kind))) from None

    def measures(self, primitive: str) -> str | None:
        """The property the primitive registered as ``primitive`` measures (``PrimitiveAction.measures``: weight,
        stiffness, friction …); None for one that measures nothing or is not registered."""
        provided = self._by_kind["primitive"].get(primitive)
        return None if provided is None else getattr(provided.record.factory, "measures", None)

    def all(self) -> list[Provided]:
        return [p for kind in KINDS for _, p in sorted(self._by_kind[kind].items())]

    def create(self, kind: str, name: str, params: dict[str, Any] | DictConfig | None = None) -> Any:
        """Build the ``kind`` plugin called ``name`` from ``params``, checked against its config schema: the factory
        gets the schema instance (``PluginRecord.takes_config``) or its fields as keyword arguments."""
        record = self.get(kind, name).record
        if record.config is not None and record.takes_config:
            return record.factory(validated_config(kind, record, params or {}))
        return record.factory(**validate_params(kind, record, params or {}))


def _property_record(record: Any) -> Any:
    """A ``Property`` a plugin returns as the ``PluginRecord`` the registry keeps (its factory gives it back)."""
    if not isinstance(record, Property):
        raise PluginError(f"muble_register_properties returned {type(record).__name__}; it returns a list of "
                          "muble.Property records")
    return PluginRecord(record.name, functools.partial(_same, record), record.description)


def _same(record: Property) -> Property:
    return record


def _options(params: dict[str, Any] | DictConfig) -> dict[str, Any]:
    if isinstance(params, DictConfig):
        params = cast("dict[str, Any]", OmegaConf.to_container(params, resolve=True))
    return {k: v for k, v in dict(params).items() if k != "name"}


def validated_config(kind: str, record: PluginRecord, params: dict[str, Any] | DictConfig) -> Any:
    """The record's config dataclass with ``params`` on its defaults, types and ranges checked
    (``muble.core.ranges.configured``): an unknown key is an error listing the valid ones."""
    assert record.config is not None, "only a record with a config dataclass has one to validate"
    return configured(record.config, _options(params), owner=f"{kind} '{record.name}'")


def validate_params(kind: str, record: PluginRecord, params: dict[str, Any] | DictConfig) -> dict[str, Any]:
    """``params`` merged onto the record's config dataclass and checked as ``validated_config`` checks them, as
    keyword arguments (``params`` as given when the record declares no config)."""
    params = _options(params)
    if record.config is None:
        return params
    node = checked_node(record.config, params, owner=f"{kind} '{record.name}'")
    return cast("dict[str, Any]", OmegaConf.to_container(node, resolve=True))


@functools.cache
def get_registry() -> Registry:
    """The process-wide registry over ``get_plugin_manager()``; ``get_registry.cache_clear()`` resets it."""
    return Registry(get_plugin_manager())


# The registry being gathered: while plugins register, what they read of the properties comes from it.
_building: Registry | None = None


# The hidden properties gathered alone, for the plugin manager they came from: what is read of them before the
# registry of everything is gathered (a module compiling its templates on import).
_properties_alone: tuple[MublePluginManager, dict[str, Property]] | None = None


def _registered_properties() -> dict[str, Property]:
    global _properties_alone
    if _building is not None:
        return _building.properties
    if get_registry.cache_info().currsize:
        return get_registry().properties
    pm = get_plugin_manager()
    if _properties_alone is None or _properties_alone[0] is not pm:
        _properties_alone = (pm, Registry(pm, kinds=("property",)).properties)
    return _properties_alone[1]


# What the core reads the registered properties through (``muble.core.physical_properties.registered``).
use_loader(_registered_properties)
