"""Savings of the MuJoCo renderer that leave every written byte as it was: the floor's reflection is not drawn where
the segmentation/depth pass shows no pixel of the floor, that pass is drawn into the single-sample buffer, and a
kept context's contents are matched by comparing arrays."""
from __future__ import annotations

import copy

import mujoco
import numpy as np
import pytest

from muble import get_registry
from muble_plugins.renderers.mujoco.atlas import ContextContents

pytestmark = pytest.mark.gl

REFLECTION = mujoco.mjtRndFlag.mjRND_REFLECTION
SEGMENT = mujoco.mjtRndFlag.mjRND_SEGMENT


def _frames(env, monkeypatch, **options):
    """Frames of the generated scene and of two arm poses, with the reflection flag of each RGB pass drawn."""
    drawn = []
    render = mujoco.mjr_render

    def recording(rect, scene, context):
        if not scene.flags[SEGMENT]:
            drawn.append(int(scene.flags[REFLECTION]))
        return render(rect, scene, context)

    monkeypatch.setattr(mujoco, "mjr_render", recording)
    renderer = get_registry().create("renderer", "mujoco", options)
    arm = env.data.qpos[:7].copy()
    frames = []
    try:
        renderer.setup(env.sync_scene_graph(), env.model)
        for k in range(3):
            env.data.qpos[:7] = arm + 0.1 * k * np.sin(np.arange(7) + k)
            mujoco.mj_forward(env.model, env.data)
            frames.append(renderer.render(env.data, env.names.cameras["front"]))
    finally:
        renderer.close()
        env.data.qpos[:7] = arm
        mujoco.mj_forward(env.model, env.data)
        monkeypatch.setattr(mujoco, "mjr_render", render)
    return frames, drawn


def _assert_same(frames, others):
    for a, b in zip(frames, others, strict=True):
        for part in ("rgb", "depth", "segmentation"):
            np.testing.assert_array_equal(getattr(a, part), getattr(b, part), err_msg=part)


def test_unseen_floor_is_drawn_without_its_reflection_and_the_frame_is_the_same(monkeypatch):
    # robosuite's stage: the table hides the floor from the front camera.
    from muble.app.config import compose
    from muble.episode.components import build_components, generated_env

    cfg = compose("run", ["output.dir=/tmp", "dataset.root=/tmp", "generator.stage=robosuite"])
    env = generated_env(cfg, build_components(cfg, renderer=False, task=False), 3)
    try:
        skipped, drawn_without = _frames(env, monkeypatch)
        always, drawn_with = _frames(env, monkeypatch, reflection_when_hidden=True)
    finally:
        env.close()
    assert drawn_without == [0, 0, 0] and drawn_with == [1, 1, 1]
    _assert_same(skipped, always)


def test_a_seen_floor_keeps_its_reflection():
    """On the original release's stage the floor shows beside the desk and its reflection changes pixels."""
    from muble.app.config import compose
    from muble.episode.components import build_components, generated_env

    cfg = compose("run", ["output.dir=/tmp", "dataset.root=/tmp", "generator.stage=original"])
    env = generated_env(cfg, build_components(cfg, renderer=False, task=False), 0)
    patch = pytest.MonkeyPatch()
    try:
        seen, drawn = _frames(env, patch)
        without, _ = _frames(env, patch, reflection=False)
    finally:
        patch.undo()
        env.close()
    assert drawn == [1, 1, 1]
    assert any(not np.array_equal(a.rgb, b.rgb) for a, b in zip(seen, without))


def test_the_id_pass_in_the_single_sample_buffer_reads_as_the_resolved_one(generated_env):
    renderer = get_registry().create("renderer", "mujoco", {})
    try:
        renderer.setup(generated_env.sync_scene_graph(), generated_env.model)
        context = renderer._context
        assert context.offSamples > 0 and context.offFBO_r  # robosuite's 4x multisampling: the direct path
        renderer._update_scene(generated_env.data, renderer._camera(generated_env.names.cameras["front"]))
        rect = mujoco.MjrRect(0, 0, renderer.config.width, renderer.config.height)
        ids, z = renderer._id_pass(rect)
        # As drawn before: into the multisampled buffer, resolved by mjr_readPixels.
        flags = renderer._scene.flags
        flags[SEGMENT], flags[mujoco.mjtRndFlag.mjRND_IDCOLOR] = 1, 1
        mujoco.mjr_render(rect, renderer._scene, context)
        resolved_ids, resolved_z = np.empty_like(ids), np.empty_like(z)
        mujoco.mjr_readPixels(resolved_ids, resolved_z, rect, context)
        flags[SEGMENT], flags[mujoco.mjtRndFlag.mjRND_IDCOLOR] = 0, 0
        np.testing.assert_array_equal(ids, resolved_ids)
        np.testing.assert_array_equal(z, resolved_z)
        assert len(np.unique(ids[..., 0])) > 5 and 0 < z.min() < z.max() < 1
    finally:
        renderer.close()


def test_context_contents_find_the_changed_mesh_slots_and_stage(generated_env):
    model = generated_env.model
    contents = ContextContents()
    assert not contents.same_stage(model)  # nothing kept: never refilled
    contents.reset(model)
    assert contents.same_stage(model) and contents.changed_slots(model) == []
    other = copy.copy(model)
    mesh = int(np.argmax(other.mesh_facenum))
    other.mesh_vert[other.mesh_vertadr[mesh]] += np.float32(1e-6)
    assert contents.changed_slots(other) == [mesh] and contents.same_stage(other)
    contents.refilled(other, [mesh])
    assert contents.changed_slots(other) == [] and contents.changed_slots(model) == [mesh]
    other.tex_data[0] ^= 1
    assert not contents.same_stage(other)
    contents.reset()
    assert not contents.same_stage(model)
