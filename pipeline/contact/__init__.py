"""Contact planning on the object's point cloud: grasps and pushes, filtered, reachable, ranked (planner.py)."""
