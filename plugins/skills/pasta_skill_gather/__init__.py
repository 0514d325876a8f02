"""The built-in gather skill: the gripper squeezes scattered dough lumps into one compact piece."""
