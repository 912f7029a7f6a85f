"""docs/agent_api.md is generated from the registry and the code (scripts/agent_api.py), so it cannot drift: this
test fails when the page differs from what the script writes. ``muble plugins --json`` shows the same parameters."""
from __future__ import annotations

import json

from tests.support.scripts import load_script


def _script():
    return load_script("scripts/agent_api.py")


def test_the_page_is_what_the_code_generates():
    script = _script()
    assert script.PAGE.read_text(encoding="utf-8") == script.render(), \
        "docs/agent_api.md differs from the code: run `python scripts/agent_api.py`"
    assert script.main(["--check"]) == 0


def test_check_fails_on_a_page_that_drifted(tmp_path, capsys):
    stale = tmp_path / "agent_api.md"
    stale.write_text(_script().render().replace("0.15", "0.2"), encoding="utf-8")
    assert _script().main(["--check", f"--out={stale}"]) == 1
    assert "python scripts/agent_api.py" in capsys.readouterr().err


def test_the_page_covers_what_an_agent_writer_needs():
    page = _script().render()
    for needed in ("`lift(height=0.15)`", "| `height` | number | no | [0.01, 0.4] | 0.15 |",  # defaults and bounds
                   "`query_com_offset`", "within 5 mm", "the offset's distance from the centre",  # answers
                   '"most slippery": the smallest', "`ascending`: smallest friction on top",  # words
                   "`front` is the half nearer the camera", "parts_at(x, y, scene.directions)",  # parts
                   "| `image` | none |", "evaluation.limit", "dataset.workers", "evaluation.decision_timeout",
                   'overrides=["protocol=shopvrb2_v2"]', "muble serve protocol=shopvrb2_v2"):
        assert needed in page, needed


def test_plugins_json_lists_every_primitives_parameters(capsys):
    from muble.app.cli import main

    assert main(["plugins", "--kind", "primitive", "--json"]) == 0
    entries = {e["name"]: e for e in json.loads(capsys.readouterr().out)}
    lift = {p["name"]: p for p in entries["lift"]["params"]}["height"]
    assert (lift["kind"], lift["low"], lift["high"], lift["default"], lift["required"]) == ("number", 0.01, 0.4,
                                                                                            0.15, False)
    assert entries["balance"]["measures"] == "com_offset" and entries["balance"]["measure_unit"] == "mm"
    assert main(["plugins", "--kind", "primitive"]) == 0
    assert "height: number in [0.01, 0.4] (optional, default 0.15): metres" in capsys.readouterr().out
