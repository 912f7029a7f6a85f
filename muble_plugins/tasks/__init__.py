"""Built-in SHOP-VRB2 tasks (ten templates, plus the stiffness family); the oracle that solves them is the agents
plugin's (``muble_plugins.agents``).

Task names are the original template ids (``measure_weight_single`` … ``stack_order``). Template files named in
the environment variable ``MUBLE_TEMPLATE_FILES`` (paths separated by the OS path separator) add their templates
as tasks too, with no Python; a plugin package registers those of its own files with ``template_tasks`` (part of
the public API, docs/plugins.md). Modules load only when the registry asks for the records.
"""
import os
from pathlib import Path

from muble import PluginRecord, hookimpl

TEMPLATE_FILES_VARIABLE = "MUBLE_TEMPLATE_FILES"


def template_tasks(path: str | os.PathLike) -> list[PluginRecord]:
    """A task for every template of the template file ``path`` (format: docs/tasks.md, "Templates as data"), as
    the records a plugin's ``muble_register_tasks`` returns: each is named by its ``template_id``, generates
    instructions, plans (so the built-in oracle solves it) and judges like the built-in ones, and takes their
    options (``instructions_per_scene``, ``extra_steps``, ``weight_margin_g``). Its program steps and word domains
    may be those of any registered hidden property (``muble_register_properties``). A mistake in the file is a
    ``ConfigError`` naming the file, the template and the field."""
    from muble_plugins.tasks.tasks import ShopVrb2TaskConfig, template_file_tasks

    return [PluginRecord(name, cls, cls.template.description, ShopVrb2TaskConfig, takes_config=True)
            for name, cls in template_file_tasks(Path(path)).items()]


@hookimpl
def muble_register_tasks() -> list[PluginRecord]:
    """The built-in templates' tasks, then those of the files named in ``MUBLE_TEMPLATE_FILES``."""
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
