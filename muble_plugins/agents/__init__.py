"""Built-in agents: the oracle (the task's plan, replanned after every primitive) and a random baseline.

Modules load only when the registry asks for the records.
"""
from muble import PluginRecord, hookimpl


@hookimpl
def muble_register_agents() -> list[PluginRecord]:
    from muble_plugins.agents.oracle import OracleAgent, OracleConfig
    from muble_plugins.agents.random_agent import RandomAgent, RandomConfig

    return [
        PluginRecord("oracle", OracleAgent, "executes the ground-truth program, replanning after every primitive "
                     "(agent.closed_loop=false: planned once, the open-loop control)", OracleConfig, takes_config=True),
        PluginRecord("random", RandomAgent, "uniformly random primitives on random objects", RandomConfig,
                     takes_config=True),
    ]
