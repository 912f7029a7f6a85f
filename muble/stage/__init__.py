"""The tabletop: the table's named parts and the stages it stands on, free places and objects' footprints on it,
objects at rest, planar geometry and the scene camera."""
