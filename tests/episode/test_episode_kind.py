"""Gymnasium's reset options and ``muble serve``'s episode documents name an episode by the same keys, read by one
function (``muble.episode.sources.episode_kind``)."""
from __future__ import annotations

import pytest

from muble.episode.sources import episode_kind


@pytest.mark.parametrize("request_, kind", [
    ({"scene_index": 3}, "generated"),
    ({"scene_index": 3, "template": "move_single"}, "generated"),
    ({"split": "val", "index": 0}, "stored"),
    ({"scene": {}, "instruction": {}}, "data"),
    ({"template": "move_single"}, None),  # a template alone names no scene
    ({"split": "val"}, None),
    ({"scene_index": 1, "split": "val", "index": 0}, None),  # two forms at once: neither
    ({}, None),
    ([("scene_index", 1)], None),
    ("scene_index", None),
])
def test_episode_kind_reads_the_keys(request_, kind):
    assert episode_kind(request_) == kind
