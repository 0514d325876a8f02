"""Built-in planner plugin 'prefix_beam': beam search over skill prefixes, then the shared optimiser on the best full sequences."""
