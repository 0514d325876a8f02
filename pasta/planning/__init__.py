"""Planning machinery shared by the planner plugins (the batched latent plan optimiser)."""
