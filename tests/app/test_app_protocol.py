"""The frozen protocol end to end: `muble generate protocol=...` reproduces the recorded files here, two clean runs
give one data hash, and `muble eval protocol=...` labels results with the protocol only on its data.

The whole mini split takes minutes to generate; the first indices are checked file by file against the manifest
recorded in the package, which is what makes the recorded hash reproducible (every index is generated on its own
from (seed, split, index)).
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from muble.app.config import compose
from muble.dataset.protocol import data_manifest, manifest_hash, protocol_of, recorded_manifest

pytestmark = pytest.mark.slow

MUBLE = [sys.executable, "-m", "muble.app.cli"]
SMALL = ["protocol=shopvrb2_v1", "protocol.splits.mini.size=2"]


def muble(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    env = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}
    return subprocess.run([*MUBLE, *args], cwd=cwd, env=env, capture_output=True, text=True, timeout=900)


@pytest.fixture(scope="module")
def generated(tmp_path_factory):
    """The first two indices of the mini split, generated twice in clean folders (1 and 2 workers)."""
    base = tmp_path_factory.mktemp("protocol")
    roots = []
    for workers in (1, 2):
        root = base / f"data{workers}"
        # The recorded hash is the whole split's: with two indices it must not be checked, so it is unset here.
        done = muble("generate", *SMALL, "protocol.splits.mini.sha256=null", f"dataset.root={root}",
                     f"dataset.workers={workers}", f"hydra.run.dir={base / f'gen{workers}'}", cwd=base)
        assert done.returncode == 0, done.stderr[-3000:]
        assert "protocol shopvrb2_v1 split mini: data sha256" in done.stdout
        roots.append(root)
    return base, roots


def test_the_protocol_regenerates_the_recorded_files(generated):
    _, roots = generated
    recorded = recorded_manifest(protocol_of(compose("generate", ["protocol=shopvrb2_v1"])), "mini")
    assert recorded is not None and len(recorded) == 200  # 100 scenes + 100 instructions
    first = data_manifest(roots[0], "mini")
    assert len(first) == 4
    assert all(recorded[path] == sha for path, sha in first.items()), \
        {p: (recorded.get(p), s) for p, s in first.items() if recorded.get(p) != s}
    # Two clean runs, one and two workers: the same files, so the same data hash.
    assert data_manifest(roots[1], "mini") == first
    stamp = json.loads((roots[0] / "protocol_mini.json").read_text())
    assert stamp["data_sha256"] == manifest_hash(first) and stamp["protocol"] == "shopvrb2_v1"


def test_the_recorded_hash_is_the_recorded_manifests():
    cfg = compose("generate", ["protocol=shopvrb2_v1"])
    protocol = protocol_of(cfg)
    assert manifest_hash(recorded_manifest(protocol, "mini")) == protocol["splits"]["mini"]["sha256"]


def test_eval_labels_only_the_protocols_data(generated):
    base, roots = generated
    root = roots[0]
    found = manifest_hash(data_manifest(root, "mini"))
    out = base / "eval_ok"
    done = muble("eval", *SMALL, f"protocol.splits.mini.sha256={found}", "agent=random", f"dataset.root={root}",
                 "dataset.workers=1", "benchmark.track=language", f"hydra.run.dir={out}", cwd=base)
    assert done.returncode == 0, done.stderr[-3000:]
    report = json.loads((out / "report.json").read_text())
    assert (report["protocol"], report["track"], report["mode"]) == ("shopvrb2_v1", "language", "graph")
    assert report["protocol_data"]["matches"] is True and report["protocol_data"]["data_sha256"] == found
    results = json.loads((out / "results.json").read_text())
    assert results["protocol"] == "shopvrb2_v1" and results["data_sha256"] == found
    # Another hash recorded than the data's: refused before any episode, with the files that differ named.
    bad = base / "eval_bad"
    done = muble("eval", *SMALL, "protocol.splits.mini.sha256=" + "0" * 64, "agent=random",
                 f"dataset.root={root}", "dataset.workers=1", f"hydra.run.dir={bad}", cwd=base)
    assert done.returncode == 2, (done.returncode, done.stderr[-2000:])
    assert "not protocol shopvrb2_v1's" in done.stderr and "Traceback" not in done.stderr
    assert not (bad / "report.json").exists() and not list(bad.glob("episodes_*.jsonl"))
    # A changed scene file is named.
    scene = next((root / "mini" / "scenes").glob("*.json"))
    scene.write_text(scene.read_text().replace('"split"', '"split" ', 1))
    done = muble("eval", *SMALL, f"protocol.splits.mini.sha256={found}", "agent=random", f"dataset.root={root}",
                 "dataset.workers=1", f"hydra.run.dir={base / 'eval_changed'}", cwd=base)
    assert done.returncode == 2 and "1 of its files differ" in done.stderr and scene.name in done.stderr, done.stderr[-2000:]
