"""The plugin system: entry-point discovery, duplicate names, import errors, autoload switch, registry lookups."""
from __future__ import annotations

import pytest

from muble import ConfigError, PluginError
from muble.plugins.hookspecs import hookimpl
from muble.plugins.manager import make_plugin_manager
from muble.plugins.records import KINDS
from muble.plugins.registry import Registry

SENSOR_MODULE = '''
import muble

class Clock(muble.Sensor):
    def __init__(self, scale: float = 1.0):
        self.scale = scale
    def read(self, env):
        return {{"time": env.data.time * self.scale}}

@muble.hookimpl
def muble_register_sensors():
    return [muble.PluginRecord("{name}", Clock, "simulation time")]
'''


def test_external_plugin_is_discovered_through_its_entry_point(fake_distribution):
    fake_distribution("acme-sensors", {"acme": "acme_sensors"}, {"acme_sensors": SENSOR_MODULE.format(name="clock")})
    registry = Registry(make_plugin_manager())
    provided = registry.get("sensor", "clock")
    assert provided.plugin == "acme" and provided.distribution == "acme-sensors"
    assert registry.create("sensor", "clock", {"scale": 2.0}).scale == 2.0


def test_two_providers_of_one_name_raise_naming_both(fake_distribution):
    fake_distribution("acme-a", {"acme_a": "acme_a"}, {"acme_a": SENSOR_MODULE.format(name="clock")})
    fake_distribution("acme-b", {"acme_b": "acme_b"}, {"acme_b": SENSOR_MODULE.format(name="clock")})
    with pytest.raises(PluginError) as err:
        Registry(make_plugin_manager())
    message = str(err.value)
    assert "sensor 'clock'" in message
    assert "acme_a" in message and "acme-a" in message and "acme_b" in message and "acme-b" in message


def test_plugin_whose_import_fails_is_named(fake_distribution):
    fake_distribution("broken-plugin", {"broken": "broken_mod"}, {"broken_mod": "import not_a_module_xyz\n"})
    with pytest.raises(PluginError) as err:
        make_plugin_manager()
    assert "'broken'" in str(err.value) and "broken-plugin" in str(err.value)
    assert "not_a_module_xyz" in str(err.value)
    assert isinstance(err.value.__cause__, ImportError)


def test_disable_autoload_skips_external_but_keeps_builtins(fake_distribution, monkeypatch):
    fake_distribution("acme-sensors", {"acme": "acme_sensors"}, {"acme_sensors": SENSOR_MODULE.format(name="clock")})
    monkeypatch.setenv("MUBLE_DISABLE_PLUGIN_AUTOLOAD", "1")
    pm = make_plugin_manager()
    assert not pm.has_plugin("acme")
    assert set(pm.distributions.values()) == {"muble"}  # only built-ins
    # An explicitly requested plugin still loads.
    monkeypatch.setenv("MUBLE_PLUGINS", "acme")
    assert make_plugin_manager().has_plugin("acme")


def test_unknown_names_list_the_valid_ones(muble_registry):
    with pytest.raises(PluginError) as err:
        muble_registry.get("renderer", "nope")
    assert "unknown renderer 'nope'" in str(err.value)
    for name in muble_registry.names("renderer"):
        assert name in str(err.value)
    with pytest.raises(PluginError, match="valid plugin kind names"):
        muble_registry.names("teleporter")


def test_mistyped_plugin_option_is_an_error(muble_registry):
    with pytest.raises(ConfigError) as err:
        muble_registry.create("renderer", "mujoco", {"widht": 10})
    assert "widht" in str(err.value) and "width" in str(err.value)


class _InCode:
    """A plugin registered in code, for the hook tests below."""

    @hookimpl
    def muble_register_agents(self):
        from muble import Agent

        class Idle(Agent):
            def act(self, instruction, observation):
                return None

        return [__import__("muble").PluginRecord("idle", Idle, "does nothing")]


def test_registration_must_return_records():
    class Bad:
        @hookimpl
        def muble_register_tasks(self):
            return ["not a record"]

    with pytest.raises(PluginError, match="must return a list of muble.PluginRecord"):
        Registry(make_plugin_manager(extra_plugins=(Bad(),)))


# One test per hook: each registers through that hook and is found under its kind.
@pytest.mark.parametrize("kind", sorted(KINDS))
def test_every_registration_hook_registers_its_kind(kind):
    hook_name = KINDS[kind]

    class One:
        pass

    def impl(self):
        from muble import PluginRecord

        return [PluginRecord(f"test-{kind}", dict, "a record for the hook test")]

    setattr(One, hook_name, hookimpl(impl))
    registry = Registry(make_plugin_manager(extra_plugins=(One(),)))
    assert registry.get(kind, f"test-{kind}").record.factory is dict


def test_muble_config_searchpath_hook():
    class Paths:
        @hookimpl
        def muble_config_searchpath(self):
            return ["pkg://somewhere.conf"]

    from muble.app.config import searchpath_override

    registry = Registry(make_plugin_manager(extra_plugins=(Paths(),)))
    assert "pkg://somewhere.conf" in searchpath_override(registry)[0]
