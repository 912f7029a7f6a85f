"""The MuBlE core: interfaces, value types, errors and the scene graph. It never imports a plugin."""
