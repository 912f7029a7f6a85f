"""Records ``reach_decisions.json.gz``: candidate layouts as the scene generator hands them to its reach check, and
the check's answer for each (``None``: accepted, else the reason), so that a faster check can be proven to decide
the same. Run from the repository root with the check to record (the fixture in the repository was recorded at
commit 59a4fc7, before the check was made faster):

    python tests/generation/data/record_reach_decisions.py tests/generation/data/reach_decisions.json.gz

Layouts: 250 scenes of the built-in generator (seed 37, the rest check on) and 50 crowded ones (seed 38, 6 or 7
objects); every layout that reached the reach check is kept, the rejected ones included.
"""
from __future__ import annotations

import gzip
import json
import os
import sys

os.environ.setdefault("MUJOCO_GL", "egl")

from muble import get_registry  # noqa: E402
from muble.core.errors import SceneGenerationError  # noqa: E402
from muble.generation import SceneGenerator  # noqa: E402
from muble.generation.reachability import ReachCheck  # noqa: E402
from muble.io.scene_io import scene_from_dict, scene_to_dict  # noqa: E402
from muble.sim.build import object_models  # noqa: E402
from muble_conf import group_defaults  # noqa: E402

RUNS = ((37, 250, {}), (38, 50, {"min_objects": 6, "count_probabilities": [0.5, 0.5]}))


def layouts() -> list[dict]:
    """Scene dictionaries of every layout the generator's reach check was asked about (what a check needs: no
    relationships, directions or pixel coordinates)."""
    builtin = {**group_defaults("generator", "shopvrb2"), "object_set": "shopvrb2", "stability": True}
    out: list[dict] = []
    check = ReachCheck(None, "approach")

    def recording(scene, models):
        d = scene_to_dict(scene)
        for key in ("relationships", "directions"):
            d.pop(key, None)
        for obj in d["objects"]:
            obj.pop("pixel_coords", None)
        out.append(d)
        return check(scene, models)

    for seed, count, options in RUNS:
        generator = SceneGenerator({**builtin, **options}, seed=seed, reach_check=recording)
        for index in range(count):
            try:
                generator.generate(index)
            except SceneGenerationError:
                pass
        generator.close()
    return out


def main(path: str) -> None:
    objects = get_registry().create("object_set", "shopvrb2")
    check = ReachCheck(None, "approach")
    records = []
    for d in layouts():
        scene = scene_from_dict(d)  # decided as the test reads it back
        records.append({"scene": d, "decision": check(scene, object_models(scene, objects))})
    with gzip.open(path, "wt") as f:
        json.dump({"layouts": records}, f, separators=(",", ":"))


if __name__ == "__main__":
    main(sys.argv[1])
