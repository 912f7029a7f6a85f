"""Material properties of the SHOP-VRB2 objects that the object sets and the synthetic scenes both draw from."""

# Ground-truth contact stiffness (N/m) of the object as a whole when pressed by a gripper jaw or resting on
# the table: the structural stiffness of thin-walled household items (a squeezed cup wall, a can side wall),
# not the Young's modulus of the material. Ordered so that squeeze can tell the classes apart; the upper ends
# stay below what a 2 ms contact time constant allows for objects of ~60 g and more.
STIFFNESS_RANGE = {
    "rubber": (4_000.0, 8_000.0),
    "plastic": (9_000.0, 20_000.0),
    "metal": (25_000.0, 50_000.0),
    "wooden": (40_000.0, 70_000.0),
    "glass": (70_000.0, 110_000.0),
    "ceramic": (70_000.0, 110_000.0),
}
