"""The tabletop: the stages and where the table's named parts lie on them, the layout sampler of new scenes, free
places and objects' footprints on the table, objects settled and at rest, planar geometry and the scene camera."""
