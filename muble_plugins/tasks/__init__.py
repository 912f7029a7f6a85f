"""Built-in SHOP-VRB2 tasks (ten templates, plus the stiffness family); the oracle that solves them is the agents
plugin's (``muble_plugins.agents``).

Task names are the original template ids (``measure_weight_single`` … ``stack_order``). Template files named in
the environment variable ``MUBLE_TEMPLATE_FILES`` (paths separated by the OS path separator) add their templates
as tasks too, with no Python. Modules load only when the registry asks for the records.
"""
import os

from muble import PluginRecord, hookimpl

TEMPLATE_FILES_VARIABLE = "MUBLE_TEMPLATE_FILES"


@hookimpl
def muble_register_tasks() -> list[PluginRecord]:
    from muble_plugins.tasks.tasks import TASK_CLASSES, ShopVrb2TaskConfig, template_file_tasks

    classes = dict(TASK_CLASSES)
    for path in filter(None, os.environ.get(TEMPLATE_FILES_VARIABLE, "").split(os.pathsep)):
        added = template_file_tasks(path)
        taken = sorted(set(added) & set(classes))
        if taken:
            from muble import ConfigError

            raise ConfigError(f"{path} (from {TEMPLATE_FILES_VARIABLE}): template ids {taken} are already tasks; "
                              "rename them")
        classes.update(added)
    return [PluginRecord(name, cls, cls.template.description, ShopVrb2TaskConfig, takes_config=True)
            for name, cls in classes.items()]
