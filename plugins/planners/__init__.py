"""Built-in planners plugins."""
