"""Built-in planner plugin 'receding_horizon': optimise a window of steps, commit the first, slide (long tasks)."""
