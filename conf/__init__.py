"""Hydra configuration groups of MuBlE (installed as ``muble_conf``)."""
