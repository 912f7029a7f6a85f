"""MuBlE built-in plugins. Each subpackage registers through the ``muble`` entry point group."""
