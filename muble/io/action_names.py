"""Primitive names as this project registers them and as the original MuBlE release wrote them.

The original sequence files name the gripper steps differently: ``approach_grasp`` (here ``approach``),
``grasp`` (``close_gripper``), ``pick_up`` (``lift``), ``put_down`` (``lower``) and ``release``
(``open_gripper``); ``move`` is the same. The original has no ``weigh`` or ``squeeze`` step (it read the weight
while holding), so those keep their names, as does any other registered primitive. The mapping is one-to-one, so
a name converts back exactly.
"""
from __future__ import annotations

from muble.core.errors import ConfigError, unknown_name
from muble.core.types import ActionCall

# This project's primitive name -> the original release's.
ORIGINAL_NAMES = {
    "approach": "approach_grasp",
    "close_gripper": "grasp",
    "lift": "pick_up",
    "lower": "put_down",
    "open_gripper": "release",
}
REGISTRY_NAMES = {original: name for name, original in ORIGINAL_NAMES.items()}
# ``episode.action_names``: how sequence files name the primitives.
STYLES = ("registry", "original")


def to_original(name: str) -> str:
    """The original release's name for the registered primitive ``name`` (unchanged where it has none)."""
    return ORIGINAL_NAMES.get(name, name)


def from_original(name: str) -> str:
    """The registered primitive an original name stands for (unchanged where it is the same)."""
    return REGISTRY_NAMES.get(name, name)


def check_style(style: str) -> str:
    if style not in STYLES:
        raise ConfigError(unknown_name("action name style", str(style), STYLES))
    return style


def named(name: str, style: str) -> str:
    """``name`` (a registered primitive) as written in the ``style`` (``registry`` or ``original``)."""
    return to_original(name) if check_style(style) == "original" else name


def call_from_original(call: ActionCall) -> ActionCall:
    """An action call written with an original name, as the registered primitive's call."""
    return ActionCall(from_original(call.name), dict(call.params))
