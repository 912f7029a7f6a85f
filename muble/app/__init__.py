"""Hydra applications and the ``muble`` command line."""
