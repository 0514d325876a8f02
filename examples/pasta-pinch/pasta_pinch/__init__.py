"""pasta-pinch: an example third-party pasta plugin (a gripper tool, a 2 -> 1 pinch skill, a beam planner)."""
