"""Training of the learned modules with one shared loop (demonstrations are read with :mod:`pasta.demos.data`).

- :mod:`pasta.train.loop`: :func:`~pasta.train.loop.fit`, the loop (seeded, resumable, best-by-validation);
- :mod:`pasta.train.vae`, :mod:`pasta.train.feasibility`, :mod:`pasta.train.cost`: per-module data,
  losses and held-out figures;
- :mod:`pasta.train.policy` (+ :mod:`pasta.train.policy_data`): behaviour cloning of a skill policy with
  hindsight goals;
- :mod:`pasta.train.reset`: a policy's learned reset (start) pose;
- :mod:`pasta.train.select`: a policy's stopping rule, chosen on validation configs;
- :mod:`pasta.train.evaluate`: single-skill evaluation of learned / heuristic / expert controllers;
- :mod:`pasta.train.run`: :func:`~pasta.train.run.train`, what ``pasta train`` calls.

The networks they train, and their loading at run time, live in :mod:`pasta.nn` and :mod:`pasta.policy`.
"""
