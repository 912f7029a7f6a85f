"""Scene-level ground truth in the SHOP-VRB2 schema: directions, relationships, pixel coordinates, COCO masks."""
from __future__ import annotations

import numpy as np

from muble.core.scene import RLE
from muble.stage.camera import CameraParams


def directions(camera: CameraParams) -> dict[str, list[float]]:
    """Unit vectors of behind/front/left/right/above/below as the camera sees the table plane.

    "behind" is the camera's viewing direction flattened onto the table, "right" the image's +x axis flattened.
    """
    forward = -camera.rotation[:, 2]
    right = camera.rotation[:, 0]
    behind = np.array([forward[0], forward[1], 0.0])
    behind /= np.linalg.norm(behind)
    right = np.array([right[0], right[1], 0.0])
    right /= np.linalg.norm(right)
    out = {"behind": behind, "front": -behind, "left": -right, "right": right,
           "above": np.array([0.0, 0.0, 1.0]), "below": np.array([0.0, 0.0, -1.0])}
    return {k: [float(x) for x in v] for k, v in out.items()}


def relationships(positions: list[np.ndarray], dirs: dict[str, list[float]], eps: float = 0.0
                  ) -> dict[str, list[list[int]]]:
    """For each relation and object i, the objects j that lie in that direction from i (CLEVR's rule)."""
    out: dict[str, list[list[int]]] = {}
    for rel in ("behind", "front", "left", "right"):
        d = np.asarray(dirs[rel])
        out[rel] = [[j for j, pj in enumerate(positions) if j != i and _along(pj, pi, d) > eps]
                    for i, pi in enumerate(positions)]
    return out


def _along(a, b, direction) -> float:
    """``(a - b) . direction`` summed in a fixed order (a BLAS dot's last bits depend on the CPU's kernel)."""
    return ((float(a[0]) - float(b[0])) * float(direction[0]) + (float(a[1]) - float(b[1])) * float(direction[1])
            + (float(a[2]) - float(b[2])) * float(direction[2]))


# Decimal places of the floats the generator writes (positions and sizes to a nanometre, angles to a nanodegree):
# far below what any check or simulation resolves, and far above the last bits in which two CPUs' arithmetic may
# differ, so a value computed a rounding error apart on another machine is written the same.
FILE_DECIMALS = 9


def rounded(value):
    """``value`` (a float, or lists, tuples and dicts of them) with every float rounded to ``FILE_DECIMALS``
    places; ints, bools, strings and None unchanged."""
    if isinstance(value, bool) or value is None or isinstance(value, (int, str)):
        return value
    if isinstance(value, dict):
        return {k: rounded(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [rounded(v) for v in value]
    if isinstance(value, np.ndarray):
        return rounded(value.tolist())
    return round(float(value), FILE_DECIMALS) + 0.0  # + 0.0: no negative zero


def pixel_coords(camera: CameraParams, position: np.ndarray) -> list:
    """[u, v, depth] of a world point: integer pixel column and row, depth along the view axis in metres."""
    u, v, depth = camera.project(np.asarray(position)[None])[0]
    return [int(round(u)), int(round(v)), float(depth)]


def encode_mask(mask: np.ndarray) -> RLE:
    """A boolean (H, W) mask as compressed COCO RLE."""
    from pycocotools import mask as coco

    rle = coco.encode(np.asfortranarray(mask.astype(np.uint8)))
    return RLE(size=[int(v) for v in rle["size"]], counts=rle["counts"].decode("ascii"))


def encode_masks(segmentation: np.ndarray, labels: list[int]) -> list[RLE]:
    """``encode_mask(segmentation == label)`` for each label, transposing the label image once.

    COCO RLE runs down columns, so each mask must be column-major; comparing on the transposed image gives
    that layout without a copy per mask.
    """
    from pycocotools import mask as coco

    transposed = np.ascontiguousarray(segmentation.T)
    out = []
    for label in labels:
        rle = coco.encode((transposed == label).view(np.uint8).T)
        out.append(RLE(size=[int(v) for v in rle["size"]], counts=rle["counts"].decode("ascii")))
    return out


def decode_mask(rle: RLE) -> np.ndarray:
    from pycocotools import mask as coco

    return coco.decode({"size": list(rle.size), "counts": rle.counts.encode("ascii")}).astype(bool)


def apply_masks(scene, segmentation: np.ndarray) -> None:
    """Set every object's, the table's and the robot's mask from a segmentation image of the scene's camera."""
    from muble.core.types import SEG_ROBOT, SEG_TABLE

    for obj in scene.objects:
        obj.mask = encode_mask(segmentation == obj.id)
    scene.table = {**(scene.table or {}), "mask": encode_mask(segmentation == SEG_TABLE)}
    scene.robot = {**(scene.robot or {}), "mask": encode_mask(segmentation == SEG_ROBOT)}
