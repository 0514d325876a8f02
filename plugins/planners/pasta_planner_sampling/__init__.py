"""Built-in planner plugin 'sampling': the same search without gradients: cross-entropy method over sub-goal latents."""
