"""Procedural generation of SHOP-VRB2 scenes."""
