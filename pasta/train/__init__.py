"""Training of the learned modules with one shared loop (demonstrations are read with :mod:`pasta.demos.data`).

- :mod:`pasta.train.loop`: :func:`~pasta.train.loop.fit`, the loop (seeded, resumable, best-by-validation);
- :mod:`pasta.train.vae`, :mod:`pasta.train.feasibility`, :mod:`pasta.train.cost`: per-module data,
  losses and held-out figures;
- :mod:`pasta.train.run`: :func:`~pasta.train.run.train`, what ``pasta train`` calls.
"""
