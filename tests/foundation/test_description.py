"""The URDF and the MuJoCo model are generated from one spec and agree with the facts sheet and each other."""

import itertools

import numpy as np
import pinocchio as pin
import pytest

from drivers.description import load_robot_spec
from drivers.description.urdf import build_urdf

SPEC = load_robot_spec()


@pytest.fixture(scope="module")
def pin_model():
    model = pin.buildModelFromXML(build_urdf(SPEC))
    return model, model.createData()


def frame_pose(model, data, q_arm, frame):
    q = np.concatenate([q_arm, [0.02, 0.02]])
    pin.framesForwardKinematics(model, data, q)
    return data.oMf[model.getFrameId(frame)]


def test_urdf_zero_configuration_matches_facts_check(pin_model):
    model, data = pin_model
    link7 = frame_pose(model, data, np.zeros(7), "link7")
    tcp = frame_pose(model, data, np.zeros(7), "link_tcp")
    np.testing.assert_allclose(link7.translation, [0.206, 0.0, 0.1205], atol=1e-4)
    np.testing.assert_allclose(tcp.translation, [0.206, 0.0, -0.0515], atol=1e-4)
    np.testing.assert_allclose(link7.rotation, np.diag([1.0, -1.0, -1.0]), atol=1e-4)  # rpy (pi, 0, 0)


def test_urdf_has_limits_inertias_and_primitive_collisions(pin_model):
    model, _ = pin_model
    names = list(model.names)[1:]
    assert names[:7] == list(SPEC.joint_names)
    np.testing.assert_allclose(model.lowerPositionLimit[:7], SPEC.lower)
    np.testing.assert_allclose(model.upperPositionLimit[:7], SPEC.upper)
    assert model.inertias[1].mass == pytest.approx(2.382)
    geoms = pin.buildGeomFromUrdfString(model, build_urdf(SPEC), pin.COLLISION)
    kinds = {type(g.geometry).__name__ for g in geoms.geometryObjects}
    assert kinds <= {"Box", "Cylinder", "Sphere"}  # primitives only, no meshes


def test_mujoco_model_matches_urdf_kinematics(pin_model, stepped_profile):
    from drivers.sim.gl import mujoco
    from drivers.sim.world import SimWorld

    model, data = pin_model
    world = SimWorld(stepped_profile.sim, stepped_profile.camera)
    m, d = world.model, mujoco.MjData(world.model)
    rng = np.random.default_rng(0)
    for _ in range(20):
        q = rng.uniform(np.maximum(SPEC.lower, -np.pi), np.minimum(SPEC.upper, np.pi))
        d.qpos[world.arm_qpos] = q
        mujoco.mj_kinematics(m, d)
        T_pin = frame_pose(model, data, q, "link_tcp")
        np.testing.assert_allclose(d.site("tcp").xpos, T_pin.translation, atol=1e-6)
        np.testing.assert_allclose(d.site("tcp").xmat.reshape(3, 3), T_pin.rotation, atol=1e-6)
    for name, lo, hi in zip(SPEC.joint_names, SPEC.lower, SPEC.upper, strict=True):
        np.testing.assert_allclose(m.joint(name).range, [lo, hi])


def test_gripper_sdk_mapping_round_trips_and_is_monotonic():
    g = SPEC.gripper
    assert g.sdk_to_width(850) == pytest.approx(g.max_width_m)
    assert g.sdk_to_width(0) == pytest.approx(g.min_width_m)
    widths = [g.sdk_to_width(p) for p in range(0, 851, 50)]
    assert all(b > a for a, b in itertools.pairwise(widths))
    for w in np.linspace(g.min_width_m, g.max_width_m, 17):
        assert g.sdk_to_width(g.width_to_sdk(w)) == pytest.approx(w, abs=1e-9)
