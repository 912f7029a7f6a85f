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
- a closed container with loose contents (``ObjectModel.contents_mass``): cavity walls ``obj{i}_wall{k}``
  (k = 0 … 5) on its body, and a world body ``obj{i}_contents`` (free joint ``obj{i}_contents_joint``, ball geom
  ``obj{i}_contents_col``), which ``body_xml`` holds after the object's body
Every name starts with ``obj{i}`` followed by ``_`` or the end, so segmentation (geom id → name → object id)
and contact reports map back to the scene graph by ``object_id_from_name``.

Groups: collision geoms are in geom group 3 (hidden by default, they collide: ``contype=conaffinity=1``);
the visual geom is in group 2 and collides with nothing (``contype=conaffinity=0``); grasp sites are group 4.
Cavity walls and contents are in group 3 too and meet each other only (``contype=conaffinity=2``,
``CONTENTS_COLLISION_CLASS``). An object with its own ``friction_coefficient`` has collision geoms of
``priority`` 1 (``FRICTION_PRIORITY``); see docs/physical_properties.md.

Contact stiffness
-----------------
Ground truth ``ObjectModel.stiffness`` K (N/m) is the stiffness a jaw feels: the force one finger presses with per
metre of its penetration into the object (what the ``squeeze`` primitive measures). MuJoCo's direct
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
    CONTENTS_COLLISION_CLASS,
    FRICTION_PRIORITY,
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
from muble.stage.geometry import quat_matrix

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

    The body's mass is ``model.mass`` exactly and its inertia ``model.inertia`` about ``model.com`` (moved by
    ``model.com_offset``). A container with loose contents (``model.contents_mass``) is two bodies: its own,
    ``mass - contents_mass`` heavy with walls round a cavity (``contents_cavity``), and the contents ball
    (``contents_mjcf``), which ``body_xml`` holds too.
    """
    body = object_body_name(object_id)
    contents = float(model.contents_mass) > 0.0
    if contents and not model.closed:
        raise ValueError(f"{model.spec.model} is no closed container: it cannot hold loose contents "
                         f"(contents_mass {model.contents_mass:g} kg)")
    mass = model.mass - model.contents_mass if contents else model.mass
    if not mass > 0.0:
        raise ValueError(f"{model.spec.model}: loose contents of {model.contents_mass:g} kg leave the container "
                         f"{mass:g} kg")
    # The jaw law reads the stiffness back from the solref and the body's own mass (``muble.sim.jaw_contact``).
    solref, solimp = contact_solref(model.stiffness, damping_ratio, mass)
    own = model.friction_coefficient
    friction = f"{model.friction if own is None else own:.6g} 0.005 0.0001"
    priority = "" if own is None else f' priority="{FRICTION_PRIORITY}"'
    assets: list[str] = []
    geoms: list[str] = []
    names: list[str] = []
    for k, part in enumerate(model.collision_parts):
        geom = f"{body}_col{k}"
        assets.append(_mesh_xml(f"{geom}_mesh", part.vertices, part.faces))
        geoms.append(
            f'<geom name="{geom}" type="mesh" mesh="{geom}_mesh" group="{COLLISION_GROUP}" contype="1" '
            f'conaffinity="1" condim="4"{priority} friction="{friction}" solref="{solref[0]:.9g} {solref[1]:.9g}" '
            f'solimp="{_floats(solimp)}" solmix="{CONTACT_SOLMIX:.6g}" rgba="{_rgba(model.rgba)}"/>'
        )
        names.append(geom)
    extra_bodies = ""
    if contents:
        walls, extra_bodies = contents_mjcf(model, body, pos, quat)
        geoms.extend(walls)
        names.extend(f"{body}_wall{k}" for k in range(len(walls)))
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
    if contents:
        inertia = inertia * (mass / model.mass)  # the same mass distribution, less the contents
    full = [inertia[0, 0], inertia[1, 1], inertia[2, 2], inertia[0, 1], inertia[0, 2], inertia[1, 2]]
    inertial = (
        f'<inertial pos="{_floats(model.centre_of_mass)}" mass="{mass:.17g}" '
        f'fullinertia="{" ".join(f"{v:.10g}" for v in full)}"/>'
    )
    body_xml = (
        f'<body name="{body}" pos="{_floats(pos)}" quat="{_floats(quat)}">'
        f'<freejoint name="{body}_joint"/>{inertial}{"".join(geoms)}{"".join(sites)}</body>{extra_bodies}'
    )
    return ObjectMjcf(asset_xml="".join(assets), body_xml=body_xml, body_name=body, geom_names=names)


# Loose contents: a ball that rolls in a box-shaped cavity inside the container's largest convex collision part,
# walled by thin boxes. The walls and the ball meet each other only (``CONTENTS_COLLISION_CLASS``), so the solid
# part round them, which the table, the fingers and other objects touch, is unchanged.
CONTENTS_WALL = 0.003  # m: thickness of the cavity's walls, all inside the container's solid part
CONTENTS_RADIUS = 0.01  # m: the ball's radius at most; smaller in a narrow cavity (``CONTENTS_FILL``)
CONTENTS_FILL = 0.4  # the ball's radius at most this share of the cavity's smallest half extent
# Crisp contacts (2.5 steps' time constant, critically damped) between the ball and the walls: each impact is a
# short force spike on the container, which the wrist sensor sees while shaking (the ``shake`` primitive).
CONTENTS_SOLREF = (0.005, 1.0)


def _halfspaces(part) -> tuple[np.ndarray, np.ndarray]:
    """Outward unit normals (F, 3) and offsets (F,) of a convex part's faces: inside is ``normals @ p <= offsets``."""
    v = np.asarray(part.vertices, dtype=float)
    f = np.asarray(part.faces, dtype=int)
    normals = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    length = np.linalg.norm(normals, axis=1)
    keep = length > 1e-12
    normals = normals[keep] / length[keep, None]
    offsets = np.einsum("ij,ij->i", normals, v[f[keep, 0]])
    flip = normals @ v.mean(axis=0) > offsets  # face winding either way: the centroid is inside
    normals[flip], offsets[flip] = -normals[flip], -offsets[flip]
    return normals, offsets


def contents_cavity(model: ObjectModel) -> tuple[np.ndarray, np.ndarray]:
    """Centre (3,) and half extents (3,) in object coordinates of the cavity the loose contents roll in: the
    largest box, centred in the largest (by bounding box) convex collision part, 0.85 of its height, whose walls
    (``CONTENTS_WALL`` thick) still lie inside that part. Raises ``ValueError`` where no cavity fits."""
    def box_volume(part):
        return float(np.prod(np.ptp(np.asarray(part.vertices, dtype=float), axis=0)))

    part = max(model.collision_parts, key=box_volume)
    v = np.asarray(part.vertices, dtype=float)
    low, high = v.min(axis=0), v.max(axis=0)
    centre, half = 0.5 * (low + high), 0.5 * (high - low)
    normals, offsets = _halfspaces(part)
    signs = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)], dtype=float)
    margin = CONTENTS_WALL + 1e-4

    def fits(scale_xy: float, half_z: float) -> bool:
        outer = np.array([half[0] * scale_xy + margin, half[1] * scale_xy + margin, half_z + margin])
        corners = centre + signs * outer
        return bool(np.all(corners @ normals.T <= offsets + 1e-9))

    half_z = 0.85 * half[2] - margin
    lo, hi = 0.0, 1.0
    for _ in range(30):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if fits(mid, half_z) else (lo, mid)
    cavity = np.array([half[0] * lo, half[1] * lo, half_z])
    if half_z <= 0 or cavity[:2].min() < 2 * CONTENTS_WALL:
        raise ValueError(f"{model.spec.model}: no cavity for loose contents fits inside its collision parts")
    return centre, cavity


def contents_radius(cavity_half: np.ndarray) -> float:
    """The loose ball's radius (m) in a cavity of ``cavity_half`` half extents."""
    return float(min(CONTENTS_RADIUS, CONTENTS_FILL * float(np.min(cavity_half))))


def contents_mjcf(model: ObjectModel, body: str, pos, quat) -> tuple[list[str], str]:
    """The cavity's wall geoms (``{body}_wall0`` … ``5``, for the container's body) and the contents body
    ``{body}_contents`` (free joint ``{body}_contents_joint``, ball geom ``{body}_contents_col``), a world body of
    its own resting on the cavity's floor: MuJoCo never lets a body touch its parent, so the ball cannot be a
    child of the container it rattles in. All of them collide in ``CONTENTS_COLLISION_CLASS`` only and sit in
    the collision geoms' group (never drawn)."""
    centre, half = contents_cavity(model)
    t = CONTENTS_WALL
    hx, hy, hz = half
    walls = [  # (centre offset, half size): floor, ceiling, -x, +x, -y, +y
        ((0, 0, -hz - t / 2), (hx + t, hy + t, t / 2)), ((0, 0, hz + t / 2), (hx + t, hy + t, t / 2)),
        ((-hx - t / 2, 0, 0), (t / 2, hy + t, hz)), ((hx + t / 2, 0, 0), (t / 2, hy + t, hz)),
        ((0, -hy - t / 2, 0), (hx, t / 2, hz)), ((0, hy + t / 2, 0), (hx, t / 2, hz)),
    ]
    contact = (f'group="{COLLISION_GROUP}" contype="{CONTENTS_COLLISION_CLASS}" '
               f'conaffinity="{CONTENTS_COLLISION_CLASS}" solref="{_floats(CONTENTS_SOLREF)}" '
               f'rgba="{_rgba(model.rgba)}"')
    geoms = [f'<geom name="{body}_wall{k}" type="box" pos="{_floats(centre + np.asarray(offset))}" '
             f'size="{_floats(size)}" condim="3" {contact}/>' for k, (offset, size) in enumerate(walls)]
    radius = contents_radius(half)
    mass = float(model.contents_mass)
    rest = centre - np.array([0.0, 0.0, hz - radius])  # on the cavity's floor, in object coordinates
    world = np.asarray(pos, dtype=float) + quat_matrix(quat) @ rest
    moment = 0.4 * mass * radius**2
    ball = (
        f'<body name="{body}_contents" pos="{_floats(world)}" quat="{_floats(quat)}">'
        f'<freejoint name="{body}_contents_joint"/>'
        f'<inertial pos="0 0 0" mass="{mass:.17g}" diaginertia="{moment:.10g} {moment:.10g} {moment:.10g}"/>'
        f'<geom name="{body}_contents_col" type="sphere" size="{radius:.6g}" condim="3" {contact}/></body>'
    )
    return geoms, ball


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
