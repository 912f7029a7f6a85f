"""Built-in primitives plugins."""
