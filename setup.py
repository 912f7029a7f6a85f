"""Package layout: ``muble`` (core), ``muble_plugins`` (the built-in plugins) and ``muble_conf`` (the Hydra configs).

Everything else about the project is in pyproject.toml; this file only lists the packages and their data.
"""
from setuptools import find_namespace_packages, find_packages, setup

# Every folder that ships files is listed as a package (the config groups under muble_conf/ are data-only
# namespace packages): setuptools warns about data in a folder missing from ``packages``.
plugin_packages = find_packages(include=["muble_plugins", "muble_plugins.*"])
conf_packages = ["muble_conf"] + [f"muble_conf.{p}" for p in find_namespace_packages("muble_conf")]
# Data-only folders of plugins (the llm agent's prompt files) are namespace packages too.
prompt_packages = ["muble_plugins.llm.prompts"]
packages = find_packages(include=["muble", "muble.*"]) + plugin_packages + prompt_packages + conf_packages
setup(
    packages=packages,
    package_data={**{p: ["*.yaml", "*.json"] for p in plugin_packages}, **{p: ["*.md"] for p in prompt_packages},
                  # The frozen protocols' shipped splits (muble_conf/protocol/*.tar.xz, about 2 MB in all).
                  **{p: ["*.yaml", "*.json", "*.tar.xz"] for p in conf_packages}},
)
