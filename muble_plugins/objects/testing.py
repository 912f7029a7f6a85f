"""Helpers for tests that need a particular object model (used by this project's tests and by plugin authors)."""
from __future__ import annotations

import numpy as np


def spec_of(objects, category, model, size="medium-sized", seed=0):
    """A sampled spec of ``category`` forced to ``model`` and ``size`` (weight kept in its sampled range)."""
    from muble_plugins.objects.catalogue import SIZE_SCALES

    spec = objects.sample(np.random.default_rng(seed), category)
    cat = objects.catalogue[category]
    factor = (SIZE_SCALES[size] / spec.scale) ** cat.mass_exponent
    spec.model, spec.shape = model, cat.model(model)[0]
    spec.size, spec.scale = size, SIZE_SCALES[size]
    spec.weight_g = round(spec.weight_g * factor, 1)
    return spec
