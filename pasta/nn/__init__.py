"""Learned spatial and skill abstraction: point-cloud VAE, set feasibility, set cost (torch).

Importing this package is cheap; torch is imported by the submodules:

- :mod:`pasta.nn.vae`: :class:`~pasta.nn.vae.PointVAE`, PointNet encoder + folding decoder;
- :mod:`pasta.nn.encoders`: the ``pc_vae`` and ``flat`` :class:`~pasta.core.Encoder` plugins;
- :mod:`pasta.nn.feasibility`: :class:`~pasta.nn.feasibility.SetFeasibility`, one per skill;
- :mod:`pasta.nn.cost`: :class:`~pasta.nn.cost.PairCost` and the ``set_cost`` :class:`~pasta.core.CostModel`;
- :mod:`pasta.nn.loading`: load trained modules from a models directory and attach them to skills;
- :mod:`pasta.nn.plugin`: the entry-point module registering the plugins (imports no torch).

Models directory layout (written by ``pasta train``)::

    ROOT/vae/                 model.safetensors + model.json (+ metrics.json, last.*)
    ROOT/flat_vae/            the whole-scene VAE of the Flat 3D baseline
    ROOT/feasibility/<skill>/ one set feasibility network per skill
    ROOT/cost/                the pairwise cost network
"""

#: sub-directory of a models root holding each trained module
VAE_DIR = "vae"
FLAT_VAE_DIR = "flat_vae"
FEASIBILITY_DIR = "feasibility"
COST_DIR = "cost"
