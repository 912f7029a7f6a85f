"""SHOP-VRB2 words: attribute order in descriptions, adjectives for shapes, plurals of category names."""
from __future__ import annotations

# Attributes a description may use, in the order the words appear ("small red ceramic cylindrical mug").
DESCRIPTION_ATTRIBUTES = ("size", "colour", "material", "shape", "name")
ATTRIBUTE_STEP = {
    "size": "filter_size",
    "colour": "filter_colour",
    "material": "filter_material",
    "shape": "filter_shape",
    "name": "filter_name",
}
# Shape values as stored in scenes -> the adjective used in text.
SHAPE_ADJECTIVE = {
    "flat": "flat",
    "hemisphere": "hemispherical",
    "cuboid": "cuboid",
    "cylindrical": "cylindrical",
    "irregularly shaped": "irregularly shaped",
}
IRREGULAR_PLURALS = {"knife": "knives", "glass": "glasses", "wine glass": "wine glasses", "food box": "food boxes",
                     "dish": "dishes", "mouse": "mice"}
GENERIC_NOUN = "object"


def plural(noun: str) -> str:
    if noun in IRREGULAR_PLURALS:
        return IRREGULAR_PLURALS[noun]
    if noun.endswith(("s", "x", "ch", "sh")):
        return noun + "es"
    return noun + "s"


def describe(description: tuple[tuple[str, str], ...], *, many: bool = False) -> str:
    """The noun phrase of a description: adjectives in ``DESCRIPTION_ATTRIBUTES`` order, then the noun."""
    values = dict(description)
    words = []
    for attr in DESCRIPTION_ATTRIBUTES[:-1]:
        if attr in values:
            words.append(SHAPE_ADJECTIVE.get(values[attr], values[attr]) if attr == "shape" else values[attr])
    noun = values.get("name", GENERIC_NOUN)
    words.append(plural(noun) if many else noun)
    return " ".join(words)
