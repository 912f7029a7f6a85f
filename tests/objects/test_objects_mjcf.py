"""The MJCF of object models: exact mass, valid inertia, names that map back to object ids."""
import mujoco
import numpy as np
import pytest

from muble.sim.object_mjcf import object_id_from_name, realised_stiffness, test_world_xml
from muble_plugins.objects.shopvrb2 import CATALOGUE

from muble_plugins.objects.testing import spec_of


@pytest.mark.parametrize("category", sorted(CATALOGUE))
def test_objects_mass_is_sampled_weight_and_inertia_positive_definite(shopvrb2, category):
    rng = np.random.default_rng(7)
    spec = shopvrb2.sample(rng, category)
    model = shopvrb2.build(spec)
    mj = mujoco.MjModel.from_xml_string(test_world_xml([(model, (0, 0, 0.1), (1, 0, 0, 0))]))
    body = mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_BODY, "obj0")
    assert abs(mj.body_mass[body] * 1000 - spec.weight_g) < 0.1
    assert np.all(mj.body_inertia[body] > 0)
    assert np.all(np.linalg.eigvalsh(model.inertia) > 0)
    # Inertia about the centre of mass: the principal moments MuJoCo derived equal ours.
    assert np.allclose(np.sort(mj.body_inertia[body]), np.sort(np.linalg.eigvalsh(model.inertia)), rtol=1e-5)


def test_objects_geom_names_map_to_object_ids(shopvrb2):
    rng = np.random.default_rng(1)
    a = shopvrb2.build(spec_of(shopvrb2, "mug", "mug1"))
    b = shopvrb2.build(shopvrb2.sample(rng, "soda can"))
    mj = mujoco.MjModel.from_xml_string(test_world_xml([(a, (0, 0, 0.1), (1, 0, 0, 0)),
                                                        (b, (0.2, 0, 0.1), (1, 0, 0, 0))]))
    ids = {}
    for g in range(mj.ngeom):
        name = mujoco.mj_id2name(mj, mujoco.mjtObj.mjOBJ_GEOM, g)
        ids.setdefault(object_id_from_name(name), []).append((name, mj.geom_group[g], mj.geom_contype[g]))
    assert None in ids  # the table
    assert len([n for n in ids[0] if "_col" in n[0]]) == len(a.collision_parts)
    assert all(grp == 3 and ct == 1 for n, grp, ct in ids[0] if "_col" in n)
    assert [(grp, ct) for n, grp, ct in ids[1] if n.endswith("_visual")] == [(2, 0)]
    assert object_id_from_name("obj12_grasp0") == 12 and object_id_from_name("object") is None


def test_objects_stiffness_maps_to_a_spring_against_the_table(shopvrb2):
    """Against the table each contact point is a spring of the object's stiffness K: the summed rest penetration
    of an upright can is its weight / K (constant impedance, the object's solimp wins the mix with the table's)."""
    spec = spec_of(shopvrb2, "soda can", "soda_can")
    sums = []
    for stiffness in (5_000.0, 20_000.0):
        spec.stiffness = stiffness
        model = shopvrb2.build(spec)
        assert model.stiffness == pytest.approx(realised_stiffness(stiffness, model.mass))
        mj = mujoco.MjModel.from_xml_string(test_world_xml([(model, (0, 0, 0.0), (1, 0, 0, 0))]))
        data = mujoco.MjData(mj)
        mujoco.mj_step(mj, data, nstep=1500)
        total_force = sum(abs(_normal_force(mj, data, i)) for i in range(data.ncon))
        assert total_force == pytest.approx(model.mass * 9.81, rel=0.02)
        depth = -sum(c.dist for c in data.contact[: data.ncon])
        assert depth == pytest.approx(model.mass * 9.81 / model.stiffness, rel=0.03)
        sums.append(depth)
    assert sums[0] / sums[1] == pytest.approx(4.0, rel=0.03)


def _normal_force(mj, data, i):
    f = np.zeros(6)
    mujoco.mj_contactForce(mj, data, i, f)
    return f[0]
