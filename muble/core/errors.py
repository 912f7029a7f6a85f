"""Error types. Each one says what went wrong *and* what to change."""
from __future__ import annotations

import difflib


class MubleError(Exception):
    """Base class of every error MuBlE raises on purpose."""


class PluginError(MubleError):
    """A plugin could not be loaded, registered or found."""


class ConfigError(MubleError):
    """A configuration value is unknown, missing or of the wrong type."""


class SceneGenerationError(ConfigError):
    """No sampled layout for a scene index passed the generator's checks within its tries.

    ``index`` is the scene index and ``reasons`` counts the rejections per check (``"placement"``,
    ``"occlusion"``, ``"stability"``, ``"reach"``, ``"not accepted"`` …).
    """

    def __init__(self, message: str, *, index: int | None = None, reasons: dict[str, int] | None = None):
        super().__init__(message)
        self.index = index
        self.reasons = dict(reasons or {})


class SceneValidationError(MubleError, ValueError):
    """A scene file or scene graph breaks the SHOP-VRB2 schema.

    ``obj`` is the object index (``None`` for scene-level fields) and ``field`` the offending key.
    """

    def __init__(self, message: str, *, obj: int | None = None, field: str | None = None):
        where = []
        if obj is not None:
            where.append(f"object {obj}")
        if field is not None:
            where.append(f"field '{field}'")
        prefix = f"{', '.join(where)}: " if where else ""
        super().__init__(prefix + message)
        self.obj = obj
        self.field = field


class PhysicsError(MubleError):
    """The simulation reached a state it cannot continue from (NaN, blow-up, object off the table)."""


class InitialStateError(PhysicsError):
    """The scene does not start at rest, so no agent may act in it (the data's fault: ``broken_scene``).

    ``obj`` is the scene id of the object that failed, ``check`` what failed (``"mass"``, ``"off_table"``,
    ``"penetration"``, ``"floating"``, ``"unstable"``, ``"moved"``, ``"unsupported"``; see
    ``muble.sim.initial_state``) and ``other`` what it conflicts with (``"table"``, ``"robot"``, another object's
    id) where there is one.
    """

    def __init__(self, message: str, *, obj: int | None = None, check: str | None = None,
                 other: int | str | None = None):
        prefix = f"initial state: object {obj} " if obj is not None else "initial state: "
        super().__init__(prefix + message)
        self.obj = obj
        self.check = check
        self.other = other


class PlanningError(MubleError):
    """No motion satisfies the request (unreachable pose, no collision-free path, time-out)."""


class RenderError(MubleError):
    """A renderer could not produce a frame (no GL context, unknown camera …)."""


class MubleDeprecationWarning(DeprecationWarning):
    """A name of the public API that moved or an interface call that changed is used the old way: it still works
    for one minor release, and the message names what to use instead (docs/plugins.md, "The public API").

    A ``DeprecationWarning`` like any other; its own class lets the plugin manager name the package that caused it
    and lets a test turn just these into errors (``-W error::muble.core.errors.MubleDeprecationWarning``)."""


def suggest(name: str, valid: list[str] | tuple[str, ...], prefix: str = "") -> str:
    """`` (did you mean 'X'?)`` for the closest valid name, a case-insensitive match first; empty if none.

    ``prefix`` is put before the suggested name (``"renderer."`` suggests ``'renderer.width'``)."""
    name, valid = str(name), [str(v) for v in valid]
    same_case = [v for v in valid if v.lower() == name.lower()]
    if same_case:
        return f" (names are case-sensitive: did you mean '{prefix}{same_case[0]}'?)"
    close = difflib.get_close_matches(name, valid, n=2, cutoff=0.6)
    if close:
        return " (did you mean " + " or ".join(f"'{prefix}{c}'" for c in close) + "?)"
    return ""


def unknown_name(kind: str, name: str, valid: list[str] | tuple[str, ...]) -> str:
    """The standard message for an unknown plugin, category or option name: the valid names listed and the closest
    one suggested (``suggest``).

    A kind with an owner, ``"split of protocol 'p'"``, puts the name after its noun: ``unknown split 'x' of protocol
    'p' (did you mean 'y'?); valid split names: …``."""
    noun, _, owner = kind.partition(" of ")
    where = f" of {owner}" if owner else ""
    options = ", ".join(sorted(str(v) for v in valid)) or "(none registered)"
    return f"unknown {noun} '{name}'{where}{suggest(name, valid)}; valid {noun} names: {options}"
