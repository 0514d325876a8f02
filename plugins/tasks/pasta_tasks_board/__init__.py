"""The board tasks of the paper: lift_spread and gather_move (a raised cutting board, spatula, gripper)."""
