"""pasta-press: a press skill whose demonstrations come from trajectory optimisation, not a scripted expert."""
