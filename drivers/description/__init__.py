"""Robot description: one YAML of numbers, from which the URDF and the MuJoCo model are generated."""

from drivers.description.spec import RobotSpec, load_robot_spec

__all__ = ["RobotSpec", "load_robot_spec"]
