"""Simulation: MuJoCo models built from scene graphs, the robosuite tabletop environment, the physics loop."""
