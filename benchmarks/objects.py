"""Object model build time per model: cold (generate meshes, write cache) vs cached (read cache), plus MJCF compile.

Run from the repository root: ``python benchmarks/objects.py``. The last line is one JSON object.
"""
from __future__ import annotations

import json
import statistics
import tempfile
import time

import mujoco

from muble.core import streams
from muble.sim.object_mjcf import test_world_xml
from muble_plugins.objects.catalogue import SIZE_SCALES
from muble_plugins.objects.shopvrb2 import ShopVrb2Objects
from muble_plugins.objects.ycb import YcbObjects


# Seeded as before named streams (muble.core.streams.legacy_stream): the figures docs/ reports were measured so.
SPECS = streams.declare_legacy("bench.objects.specs", "the sampled object of every model (0)")


def specs(objects):
    rng = streams.legacy_stream(SPECS, 0)
    for category in objects.categories():
        cat = objects.catalogue[category]
        for model in cat.variants:
            spec = objects.sample(rng, category)
            spec.model, spec.size, spec.scale = model, "medium-sized", SIZE_SCALES["medium-sized"]
            yield spec


def main() -> None:
    cold, cached, compile_ms, parts = [], [], [], []
    with tempfile.TemporaryDirectory() as cache_dir:
        for cls in (ShopVrb2Objects, YcbObjects):
            first, second = cls(cache_dir=cache_dir), cls(cache_dir=cache_dir)
            for spec in specs(first):
                t0 = time.perf_counter()
                model = first.build(spec)
                cold.append(time.perf_counter() - t0)
                t0 = time.perf_counter()
                second.build(spec)
                cached.append(time.perf_counter() - t0)
                t0 = time.perf_counter()
                mujoco.MjModel.from_xml_string(test_world_xml([(model, (0, 0, 0.05), (1, 0, 0, 0))]))
                compile_ms.append(time.perf_counter() - t0)
                parts.append(len(model.collision_parts))
    ms = lambda xs: round(1000 * statistics.median(xs), 2)  # noqa: E731
    result = {
        "benchmark": "objects", "metric": "cached_build_median", "value": ms(cached), "unit": "ms", "goal": 20.0,
        "baseline_cold_build_median_ms": ms(cold), "cold_build_max_ms": round(1000 * max(cold), 2),
        "cached_build_max_ms": round(1000 * max(cached), 2), "speedup_median": round(ms(cold) / ms(cached), 2),
        "mjcf_compile_median_ms": ms(compile_ms), "models": len(cold),
        "collision_parts_median": statistics.median(parts), "collision_parts_max": max(parts),
    }
    print(json.dumps(result))


if __name__ == "__main__":
    main()
