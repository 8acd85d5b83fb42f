"""Motion: from goal poses to supervised streaming on the arm. Every check is the safety layer's.

goals.ik_goals(world, limits, T_base_tcp, q_now)     ranked collision-free IK solutions (GoalError)
goals.tool_offset(T, d) / goals.lifted(T, h)         approach/retreat poses along the gripper axis / up
planner.Planner(world, limits).plan(q0, q1)          JointPath: direct move, else OMPL + dense re-check
planner.Planner(...).smooth(waypoints)               corners cut (extra obstacle clearance) for blending
cartesian.cartesian_path(planner, q0, T_target)      straight TCP line as joint waypoints
timing.TrajectoryTimer(limits, dt, ...).time(steps)  Ruckig timing of paths + GripperActions -> JointTrajectory
approval.approve(trajectory, world, q_current)       the gate's ApprovedTrajectory (GateRefused otherwise)
executor.Executor(arm, config, limits, gripper)      fixed-rate streaming; execute/abort/estop -> report
"""
