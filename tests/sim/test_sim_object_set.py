import numpy as np

import muble
from muble.core.scene import SceneGraph, SceneObject
from muble.sim.build import env_from_object_set


def test_sim_env_from_shopvrb2_scene_rests():
    object_set = muble.get_registry().create("object_set", "shopvrb2")
    rng = np.random.default_rng(0)
    objects = []
    for i, (x, y) in enumerate([(0.45, 0.0), (0.6, -0.2), (0.4, 0.25)]):
        spec = object_set.sample(rng)
        model = object_set.build(spec)
        objects.append(SceneObject(
            id=i, model=spec.model, name=spec.category, shape=spec.shape, size=spec.size, material=spec.material,
            colour=spec.colour, position=np.array([x, y, 0.0]), orientation=np.array([1.0, 0, 0, 0]),
            weight_gt=spec.weight_g, stackable=model.stackable, stack_base=model.stack_base,
            pickupable=model.pickupable, stiffness=spec.stiffness, scale_factor=spec.scale,
            extra={"params": spec.params}))
    env = env_from_object_set(SceneGraph(objects=objects), object_set, sensors=["objects"])
    for obj in objects:  # the rebuilt models carry the sampled mass exactly
        body = env.grasp.body_of[obj.id]
        assert env.model.body_mass[body] == obj.weight_gt / 1000.0
    env.hold(1.0)
    synced = env.sync_scene_graph()
    for obj in objects:
        assert np.linalg.norm(synced.object(obj.id).position - obj.position) < 0.003
