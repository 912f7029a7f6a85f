"""What the tests and the benchmarks share, outside the product: simple scenes, a tabletop for planners, physical
checks of object models, MuJoCo's reference passes and image likeness scores, and fake plugin distributions."""
