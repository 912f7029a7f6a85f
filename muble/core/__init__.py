"""The MuBlE core: the data model (value types, errors, object models, the scene graph) and the plugin interfaces.
It never imports a plugin."""
