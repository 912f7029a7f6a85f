"""Grasp frames of the SHOP-VRB2 shapes: how deep a grasp sits and the frames of round bodies, rims and handles.

The catalogue's procedural models (``muble_plugins.objects.shopvrb2``) and the original release's measured ones
(``muble_plugins.objects.original_models``) both build their grasps with these.
"""
from __future__ import annotations

import math

import numpy as np

from muble.core.objects import GraspFrame
from muble_plugins.objects.catalogue import grasp_quat, side, top_down

# Grasp frames place the middle of the finger pads (see grasping.GripGeometry for how each gripper's grip site
# follows). A top-down grasp puts it this far below an object's top, so that pads 16-34 mm tall lie on the
# object's upper part while the palm above them stays clear of it.
GRIP_DEPTH = 0.0165
# A rim pinch puts the pads' middle just below the rim's edge, so that their upper part is over the edge: that
# is where both walls stick out furthest, so the pads (not the fingertips below them) touch first.
RIM_DEPTH = 0.0025
STEM_GRIP_HEIGHT = 0.036  # m: a horizontal hand (about 63 mm tall) must stay off the table


def radius_at(profile, z) -> float:
    """Outer radius of an (r, z) profile at height ``z`` (clamped to its ends)."""
    rs, zs = zip(*profile)
    return float(np.interp(z, zs, rs))


def rim_frames(profile, wall, sectors, skip=None) -> list:
    """Pinches of a vessel's rim, one at the middle of each of the ``sectors`` flat wall pieces of its
    collision geometry (a flat face meets the pads, never a corner), jaws closing radially across the wall;
    ``skip(angle)`` leaves out places (a mug's handle).

    The fingers lean with the wall below the rim (from above and outside where it flares outwards, from above and
    inside where it bulges out below the rim, as on a wine glass), so that a fingertip does not meet the wall
    below the rim before the pads do.
    """
    height = profile[-1][1]
    below = height - 0.015
    lean = math.atan((profile[-1][0] - radius_at(profile, below)) / 0.015)
    z = height - RIM_DEPTH * math.cos(lean)
    outer = radius_at(profile, z)
    r = math.cos(math.pi / sectors) * (outer / math.cos(math.pi / sectors) + outer - wall) / 2
    frames = []
    for k in range(sectors):
        a = (k + 0.5) * 2 * math.pi / sectors
        if skip is not None and skip(a):
            continue
        inward = np.array([-math.cos(a), -math.sin(a), 0.0])
        down = np.array([0.0, 0.0, -1.0])
        closing = inward * math.cos(lean) - down * math.sin(lean)
        approach = inward * math.sin(lean) + down * math.cos(lean)
        frames.append(GraspFrame(np.array([r * math.cos(a), r * math.sin(a), z]), grasp_quat(closing, approach),
                                 wall / math.cos(lean)))
    return frames


def cylinder_frames(radius, grip_z) -> list:
    """Four grasps of a round body from above, ``grip_z`` high, 45 degrees apart."""
    return [top_down((0.0, 0.0, grip_z), k * math.pi / 4, 2 * radius) for k in range(4)]


def side_frames(radius, z) -> list:
    """Grasps around an upright body from the side, level and tilted down by 45 degrees, from eight directions:
    for when neighbours leave no room for the hand above it. ``z`` is kept high enough for a level hand
    (about 63 mm tall) to stay off the table."""
    z = max(z, STEM_GRIP_HEIGHT)
    return [side((0.0, 0.0, z), k * math.pi / 4, 2 * radius, pitch=pitch)
            for pitch in (0.0, math.pi / 4) for k in range(8)]


def handle_frames(centre_x, z_low, z_high, reach, thickness, height) -> list:
    """Grasps of a mug handle (a half ring in the x-z plane at +x): fingers closing across its width (y).

    From outside, horizontal and tilted down (the hand beside the mug), and from above where the handle is
    high enough for the palm to clear the mug's rim.
    """
    zc, rz = 0.5 * (z_low + z_high), 0.5 * (z_high - z_low)
    width = 1.4 * thickness  # the tube's extent across the fingers, oval cross-section included
    frames = []
    for pitch in (0.0, math.pi / 6, math.pi / 3):
        # The pads' middle on the tube's centre line, where the approach line meets its outer half.
        a = pitch / 2
        x, z = centre_x + reach * math.cos(a), zc + rz * math.sin(a)
        frames.append(side((x, 0.0, z), math.pi, width, pitch=pitch))
    z = min(height - GRIP_DEPTH, z_high - thickness)
    a = math.asin(max(-1.0, min(1.0, (z - zc) / rz)))
    frames.append(top_down((centre_x + reach * math.cos(a), 0.0, z), 0.0, width))
    return frames
