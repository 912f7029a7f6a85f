"""Task programs: the CLEVR-IEP program executor over a scene graph, and objects described in words."""
