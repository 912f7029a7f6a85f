"""Helpers for tests that need a particular object model (used by this project's tests and by plugin authors)."""
from __future__ import annotations

from muble.core import streams

SPEC_STREAM = streams.declare("objects.test_spec", "the sampled object a test asks for by category, model and size "
                              "(seed; muble_plugins.objects.testing.spec_of)")


def spec_of(objects, category, model, size="medium-sized", seed=0):
    """A sampled spec of ``category`` forced to ``model`` and ``size`` (weight kept in its sampled range)."""
    from muble_plugins.objects.catalogue import SIZE_SCALES

    spec = objects.sample(streams.stream(SPEC_STREAM, seed), category)
    cat = objects.catalogue[category]
    factor = (SIZE_SCALES[size] / spec.scale) ** cat.mass_exponent
    spec.model, spec.shape = model, cat.model(model)[0]
    spec.size, spec.scale = size, SIZE_SCALES[size]
    spec.weight_g = round(spec.weight_g * factor, 1)
    return spec
