"""Built-in SHOP-VRB2 tasks (ten templates) and agents (oracle, random).

Task names are the original template ids (``measure_weight_single`` … ``stack_order``). Modules load only when
the registry asks for the records.
"""
from muble import PluginRecord, hookimpl


@hookimpl
def muble_register_tasks() -> list[PluginRecord]:
    from muble_plugins.tasks.tasks import TASK_CLASSES, ShopVrb2TaskConfig

    return [PluginRecord(name, cls, cls.template.description, ShopVrb2TaskConfig)
            for name, cls in TASK_CLASSES.items()]


@hookimpl
def muble_register_agents() -> list[PluginRecord]:
    from muble_plugins.tasks.agents import OracleAgent, OracleConfig, RandomAgent, RandomConfig

    return [
        PluginRecord("oracle", OracleAgent, "executes the ground-truth program, replanning after every primitive",
                     OracleConfig),
        PluginRecord("random", RandomAgent, "uniformly random primitives on random objects", RandomConfig),
    ]
