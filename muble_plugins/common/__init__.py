"""What the built-in plugins share: the primitives' names and the symbolic world, the task planner, the success
checks and table geometry, symbolic roll-outs and scenes, the agents' books and the object set's material ranges.

Not a plugin: it registers nothing (no entry point) and imports no plugin package, so every plugin may import it
(tests/core/test_core_layering.py checks both).
"""
