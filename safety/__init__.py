"""Safety layer: robot model, collision world, limits and the trajectory gate.

    robot = RobotModel()                                  # safety.robot_model: FK, Jacobians, IK, dexterity
    world = CollisionWorld(robot, profile.safety, obstacles=..., points=..., held=...)   # safety.collision
    world.in_collision(q) / world.check(q)                # fast bool / every Contact with kind and names
    report = validate(trajectory, world, q_current=q)     # safety.gate: every Violation; stream only if report.ok

Submodules are imported explicitly (this package's import stays light: runtime.config needs only safety.config).
"""
