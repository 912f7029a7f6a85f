"""The plugin system: entry-point discovery, duplicate names, import errors, autoload switch, registry lookups."""
from __future__ import annotations

import pytest

from muble import ConfigError, PluginError, Property
from muble.plugins.hookspecs import hookimpl
from muble.plugins.manager import REPORTED_ENV, make_plugin_manager
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


@pytest.fixture
def unreported(monkeypatch):
    """No broken package reported yet in this process (the manager reports each once per run)."""
    monkeypatch.setenv(REPORTED_ENV, "")


def test_plugin_whose_import_fails_is_left_out_and_named_once(fake_distribution, unreported, caplog):
    fake_distribution("broken-plugin", {"broken": "broken_mod"}, {"broken_mod": "import not_a_module_xyz\n"})
    fake_distribution("acme-sensors", {"acme": "acme_sensors"}, {"acme_sensors": SENSOR_MODULE.format(name="clock")})
    with caplog.at_level("WARNING", logger="muble.plugins.manager"):
        pm = make_plugin_manager()
        registry = Registry(pm)
    (broken,) = registry.broken
    assert (broken.name, broken.distribution, broken.target, broken.stage) == \
        ("broken", "broken-plugin", "broken_mod", "import")
    assert broken.error == "ModuleNotFoundError: No module named 'not_a_module_xyz'"
    assert not pm.has_plugin("broken")
    # Everything else is there: the other installed package and MuBlE's own plugins.
    assert "clock" in registry.names("sensor") and "oracle" in registry.names("agent")
    (line,) = [r.getMessage() for r in caplog.records]
    assert "'broken-plugin'" in line and "not_a_module_xyz" in line and "pip uninstall broken-plugin" in line
    assert "\n" not in line
    # A second manager in the same run (a spawned worker inherits the environment) does not say it again.
    caplog.clear()
    with caplog.at_level("WARNING", logger="muble.plugins.manager"):
        assert [b.distribution for b in make_plugin_manager().broken] == ["broken-plugin"]
    assert caplog.records == []


BROKEN_HOOKS = {
    "raises": "    raise RuntimeError('agents table missing')\n",
    "returns strings": "    return ['greedy']\n",
}


@pytest.mark.parametrize("how", sorted(BROKEN_HOOKS))
def test_plugin_whose_registration_fails_is_left_out_with_everything_it_registered(how, fake_distribution,
                                                                                   unreported):
    module = SENSOR_MODULE.format(name="clock") + "\n@muble.hookimpl\ndef muble_register_agents():\n" + \
        BROKEN_HOOKS[how]
    fake_distribution("acme-broken", {"acme": "acme_broken"}, {"acme_broken": module})
    registry = Registry(make_plugin_manager())
    (broken,) = registry.broken
    assert (broken.distribution, broken.stage) == ("acme-broken", "muble_register_agents")
    assert ("agents table missing" if how == "raises" else "must return a list of muble.PluginRecord") in broken.error
    assert "clock" not in registry.names("sensor")  # its sensor, registered by a hook that worked, goes too
    assert "oracle" in registry.names("agent")


def test_plugin_implementing_a_hook_muble_does_not_have_is_left_out(fake_distribution, unreported):
    module = SENSOR_MODULE.format(name="clock") + "\n@muble.hookimpl\ndef muble_register_teleporters():\n" \
                                                  "    return []\n"
    fake_distribution("acme-future", {"acme": "acme_future"}, {"acme_future": module})
    registry = Registry(make_plugin_manager())
    (broken,) = registry.broken
    assert broken.stage == "registration" and "muble_register_teleporters" in broken.error
    assert "muble_register_sensors" in broken.error  # the hooks there are
    assert "clock" not in registry.names("sensor")


def test_muble_s_own_plugin_failing_to_import_is_an_error(fake_distribution):
    # A distribution named muble stands for MuBlE's own (the first one on sys.path is the one read).
    fake_distribution("muble", {"builtin_broken": "builtin_broken"}, {"builtin_broken": "import not_a_module_xyz\n"})
    with pytest.raises(PluginError) as err:
        make_plugin_manager()
    assert "MuBlE's own plugin 'builtin_broken'" in str(err.value) and "not_a_module_xyz" in str(err.value)
    assert "Reinstall MuBlE" in str(err.value) and isinstance(err.value.__cause__, ImportError)


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

    # A hidden property registers as its record (``muble.Property``), which the registry keeps as a factory of it.
    prop = Property("test_property", "weigh", lambda o: None) if kind == "property" else None

    def impl(self):
        from muble import PluginRecord

        return [prop] if prop is not None else [PluginRecord(f"test-{kind}", dict, "a record for the hook test")]

    setattr(One, hook_name, hookimpl(impl))
    registry = Registry(make_plugin_manager(extra_plugins=(One(),)))
    if prop is not None:
        assert registry.get(kind, "test_property").record.factory() is prop
        assert list(registry.properties)[-1] == "test_property"  # after MuBlE's own five
        assert list(registry.properties)[:5] == ["weight", "stiffness", "friction", "com_offset", "rattles"]
    else:
        assert registry.get(kind, f"test-{kind}").record.factory is dict


def test_a_property_hook_that_returns_something_else_is_named():
    class Bad:
        @hookimpl
        def muble_register_properties(self):
            from muble import PluginRecord

            return [PluginRecord("heat", dict)]

    with pytest.raises(PluginError, match="returns a list of muble.Property records"):
        Registry(make_plugin_manager(extra_plugins=(Bad(),)))


def test_a_property_whose_margin_a_reading_within_tolerance_can_cross_is_refused():
    with pytest.raises(ValueError, match="margin 1.5 °C must be at least 2 × the tolerance 1.0"):
        Property("heat", "feel", lambda o: None, unit="°C", superlatives=("hottest", "coldest"), tolerance=1.0,
                 margin=1.5)


def test_muble_config_searchpath_hook():
    class Paths:
        @hookimpl
        def muble_config_searchpath(self):
            return ["pkg://somewhere.conf"]

    from muble.app.config import searchpath_override

    registry = Registry(make_plugin_manager(extra_plugins=(Paths(),)))
    assert "pkg://somewhere.conf" in searchpath_override(registry)[0]
