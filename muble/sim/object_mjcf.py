"""MJCF for object models: one free body per object, convex collision geoms, a visual mesh, exact mass.

Public API
----------
``object_mjcf(model, object_id, pos, quat) -> ObjectMjcf``
    The ``<asset>`` children (``ObjectMjcf.asset_xml``) and the ``<body>`` element (``ObjectMjcf.body_xml``) of
    one object. Mesh data is written inline (``vertex``/``face`` attributes), so no asset files or asset
    dictionaries are needed: the strings can be pasted into any MJCF (robosuite's ``MujocoXML`` merge included)
    or compiled with ``mujoco.MjModel.from_xml_string``.
``test_world_xml(placements, ...) -> str``
    A standalone world: a table box whose top surface is at ``z = table_height`` plus the given objects, with
    robosuite's global physics options. ``placements`` is a list of ``(model, pos, quat)``; object ids are the
    list indices.
``contact_solref(stiffness, damping_ratio, mass) -> (solref, solimp)``, ``realised_stiffness(...)``,
``realised_damping(...)``, ``stiffness_of_solref(k, mass)``
    The mapping between a physical contact stiffness (N/m) and MuJoCo's direct-mode ``solref`` (base law; the jaw
    law on top of it is ``muble.sim.jaw_contact``).
``object_id_from_name(name) -> int | None``
    The object id encoded in a body, geom, joint or site name (``None`` for non-object names).

Naming convention (object ``i``)
--------------------------------
- body ``obj{i}``, free joint ``obj{i}_joint``
- collision geoms ``obj{i}_col{k}`` (k = 0 … n-1, one per convex part), meshes ``obj{i}_col{k}_mesh``
- visual geom ``obj{i}_visual``, mesh ``obj{i}_visual_mesh``
- grasp sites ``obj{i}_grasp{k}`` in the order of ``ObjectModel.grasp_frames``
Every name starts with ``obj{i}`` followed by ``_`` or the end, so segmentation (geom id → name → object id)
and contact reports map back to the scene graph by ``object_id_from_name``.

Groups: collision geoms are in geom group 3 (hidden by default, they collide: ``contype=conaffinity=1``);
the visual geom is in group 2 and collides with nothing (``contype=conaffinity=0``); grasp sites are group 4.

Contact stiffness
-----------------
Ground truth ``ObjectModel.stiffness`` K (N/m) is the stiffness a jaw feels: the force one finger presses with per
metre of its penetration into the object (what ``muble.sim.measure.squeeze`` measures). MuJoCo's direct
``solref = (-k, -b)`` gives each contact point the reference acceleration ``a_ref = -(b/d)·v - (k/d²)·d·r`` and the
regulariser ``R = (1-d)/d · A`` (``d`` the impedance from ``solimp``, ``A`` the diagonal approximation of the
contact's inverse mass: the sum of both bodies' ``body_invweight0``). At rest ``R·f = a_ref``, so one contact point
is a spring of ``f/r = k / ((1-d)·A)``. Two things keep this from being the object's stiffness:

- ``A`` includes the finger (``invweight0`` of a Panda finger tip is 0.33 1/kg, 6 % of a 180 g object's 1/m);
- a flat pad on a flat face yields 4 contact points, on a cylinder 1, and the finger body's own geoms touch
  too: parallel springs, so the jaw stiffness would be (points in contact) × the point stiffness.

So the per-geom ``solref`` written here is the *base* law, a point spring of K against an immovable surface
(``A = 1/m``, the table): ``k = K·(1-d)/m``. While fingers touch an object, ``muble.sim.jaw_contact.JawContacts``
rescales the object's ``k`` once per control step so that the summed normal force of both jaws is K times the
summed depth of the deepest point of each jaw (see docs/environment.md, "Stiffness"). The impedance is constant
(``solimp = (d, d, …)``) and the object's ``solmix`` is large, so the object's ``solimp`` wins against the
fingers' and the table's (MuJoCo averages solimp by solmix weight): the spring stays linear in depth. When two
geoms meet and either uses direct mode, MuJoCo takes the element-wise minimum of the solrefs: the object's
(negative) values win against the table's and the fingers' standard ones. ``k`` is capped so that the contact's
natural period ``1/sqrt(k)`` stays above two 2 ms physics steps; the stiffness actually realised is stored back in
``ObjectModel.stiffness`` by the object sets.
"""
from __future__ import annotations

import functools

from dataclasses import dataclass

import numpy as np

from muble.core.object_physics import (  # noqa: F401  (re-exported: the names and contact law live in the core)
    CONTACT_IMPEDANCE,
    CONTACT_SOLMIX,
    MAX_ACCEL_STIFFNESS,
    MIN_TIME_CONSTANT,
    contact_solref,
    object_body_name,
    object_id_from_name,
    realised_damping,
    realised_stiffness,
    stiffness_of_solref,
)
from muble.core.objects import ObjectModel

COLLISION_GROUP = 3
VISUAL_GROUP = 2
SITE_GROUP = 4

@dataclass
class ObjectMjcf:
    """The MJCF fragments of one object."""

    asset_xml: str  # <mesh …/> elements for the <asset> section
    body_xml: str  # the <body> element for <worldbody>
    body_name: str
    geom_names: list[str]  # collision geoms first, visual geom last


def _floats(values) -> str:
    return " ".join(f"{float(v):.6g}" for v in np.asarray(values, dtype=float).ravel())


def _ints(values) -> str:
    return " ".join(str(int(v)) for v in np.asarray(values).ravel())


def _mesh_xml(name: str, vertices: np.ndarray, faces: np.ndarray) -> str:
    # inertia="convex": the geoms carry no mass (the body has an explicit <inertial>), and the convex rule
    # never fails on open or thin visual meshes the way the exact volume rule can.
    vertex, face = _mesh_text(np.asarray(vertices, dtype=float).tobytes(), np.asarray(faces).tobytes(),
                              np.asarray(faces).dtype.str)
    return f'<mesh name="{name}" inertia="convex" vertex="{vertex}" face="{face}"/>'


@functools.lru_cache(maxsize=512)
def _mesh_text(vertices: bytes, faces: bytes, face_dtype: str) -> tuple[str, str]:
    """Vertex and face attribute text of a mesh, by content: a mesh met again (the same object in the next
    layout, scene or episode) is not formatted again."""
    return _floats(np.frombuffer(vertices, dtype=float)), _ints(np.frombuffer(faces, dtype=face_dtype))


def _rgba(rgba) -> str:
    return _floats(rgba)


def object_mjcf(model: ObjectModel, object_id: int, pos=(0.0, 0.0, 0.0), quat=(1.0, 0.0, 0.0, 0.0),
                damping_ratio: float = 1.0) -> ObjectMjcf:
    """The MJCF of ``model`` as object ``object_id`` at ``pos`` with orientation ``quat`` (w, x, y, z).

    The body's mass is ``model.mass`` exactly and its inertia ``model.inertia`` about ``model.com``.
    """
    body = object_body_name(object_id)
    solref, solimp = contact_solref(model.stiffness, damping_ratio, model.mass)
    friction = f"{model.friction:.6g} 0.005 0.0001"
    assets: list[str] = []
    geoms: list[str] = []
    names: list[str] = []
    for k, part in enumerate(model.collision_parts):
        geom = f"{body}_col{k}"
        assets.append(_mesh_xml(f"{geom}_mesh", part.vertices, part.faces))
        geoms.append(
            f'<geom name="{geom}" type="mesh" mesh="{geom}_mesh" group="{COLLISION_GROUP}" contype="1" '
            f'conaffinity="1" condim="4" friction="{friction}" solref="{solref[0]:.9g} {solref[1]:.9g}" '
            f'solimp="{_floats(solimp)}" solmix="{CONTACT_SOLMIX:.6g}" rgba="{_rgba(model.rgba)}"/>'
        )
        names.append(geom)
    visual = f"{body}_visual"
    assets.append(_mesh_xml(f"{visual}_mesh", model.visual.vertices, model.visual.faces))
    geoms.append(
        f'<geom name="{visual}" type="mesh" mesh="{visual}_mesh" group="{VISUAL_GROUP}" contype="0" '
        f'conaffinity="0" rgba="{_rgba(model.rgba)}"/>'
    )
    names.append(visual)
    sites = []
    for k, frame in enumerate(model.grasp_frames):
        sites.append(
            f'<site name="{body}_grasp{k}" pos="{_floats(frame.position)}" quat="{_floats(frame.quat)}" '
            f'size="0.004" group="{SITE_GROUP}" rgba="0 1 0 0.5"/>'
        )
    inertia = np.asarray(model.inertia, dtype=float)
    full = [inertia[0, 0], inertia[1, 1], inertia[2, 2], inertia[0, 1], inertia[0, 2], inertia[1, 2]]
    inertial = (
        f'<inertial pos="{_floats(model.com)}" mass="{model.mass:.17g}" '
        f'fullinertia="{" ".join(f"{v:.10g}" for v in full)}"/>'
    )
    body_xml = (
        f'<body name="{body}" pos="{_floats(pos)}" quat="{_floats(quat)}">'
        f'<freejoint name="{body}_joint"/>{inertial}{"".join(geoms)}{"".join(sites)}</body>'
    )
    return ObjectMjcf(asset_xml="".join(assets), body_xml=body_xml, body_name=body, geom_names=names)


def test_world_xml(placements, table_height: float = 0.0, table_half_size=(0.5, 0.5),
                   timestep: float = 0.002) -> str:
    """A standalone MJCF world: a table box (top at ``table_height``) and the objects ``(model, pos, quat)``.

    Global options copy robosuite's base model (elliptic cones, ``impratio`` 20) so drop and stacking tests
    see the same contact model as the environment. The table uses robosuite's table friction.
    """
    assets, bodies = [], []
    for i, (model, pos, quat) in enumerate(placements):
        mjcf = object_mjcf(model, i, pos, quat)
        assets.append(mjcf.asset_xml)
        bodies.append(mjcf.body_xml)
    hx, hy = table_half_size
    return (
        '<mujoco model="object_test_world">'
        '<compiler angle="radian" autolimits="true"/>'
        f'<option timestep="{timestep}" impratio="20" cone="elliptic"/>'
        f'<asset>{"".join(assets)}</asset>'
        '<worldbody>'
        '<light pos="0 0 3" dir="0 0 -1"/>'
        f'<geom name="table" type="box" size="{hx} {hy} 0.025" pos="0 0 {table_height - 0.025}" '
        'friction="1 0.005 0.0001" rgba="0.6 0.5 0.4 1"/>'
        f'{"".join(bodies)}'
        '</worldbody></mujoco>'
    )


# Pytest would otherwise collect the world builder as a test when it is imported into a test module.
test_world_xml.__test__ = False
