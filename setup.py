"""Package layout: ``muble`` (core), ``plugins/`` installed as ``muble_plugins``, ``conf/`` as ``muble_conf``.

Everything else about the project is in pyproject.toml; this file only maps folders to package names.
"""
from setuptools import find_packages, setup

packages = (
    find_packages(include=["muble", "muble.*"])
    + ["muble_plugins"]
    + [f"muble_plugins.{p}" for p in find_packages("plugins")]
    + ["muble_conf"]
)
setup(
    packages=packages,
    package_dir={"muble_plugins": "plugins", "muble_conf": "conf"},
    package_data={"muble_plugins": ["**/*.yaml", "**/*.json"], "muble_conf": ["**/*.yaml"]},
)
