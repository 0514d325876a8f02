"""Built-in planner plugin 'exhaustive': every skill sequence with the right cardinality, random attention, Adam on sub-goal latents (PASTA)."""
