"""Package layout: ``muble`` (core), ``plugins/`` installed as ``muble_plugins``, ``conf/`` as ``muble_conf``.

Everything else about the project is in pyproject.toml; this file only maps folders to package names.
"""
from setuptools import find_namespace_packages, find_packages, setup

# Every folder that ships files is listed as a package (the config groups under conf/ are data-only namespace
# packages): setuptools warns about data in a folder missing from ``packages``.
plugin_packages = ["muble_plugins"] + [f"muble_plugins.{p}" for p in find_packages("plugins")]
conf_packages = ["muble_conf"] + [f"muble_conf.{p}" for p in find_namespace_packages("conf")]
packages = find_packages(include=["muble", "muble.*"]) + plugin_packages + conf_packages
setup(
    packages=packages,
    package_dir={"muble_plugins": "plugins", "muble_conf": "conf"},
    package_data={**{p: ["*.yaml", "*.json"] for p in plugin_packages}, **{p: ["*.yaml"] for p in conf_packages}},
)
