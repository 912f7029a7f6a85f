"""Built-in objects plugins."""
