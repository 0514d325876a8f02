"""pasta-pinch: an example third-party pasta plugin (a pincer tool: a parallel gripper, a 2 -> 1 pinch skill, a beam planner)."""
