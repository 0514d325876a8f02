"""Learned spatial and skill abstraction: point-cloud VAE, set feasibility, set cost (torch).

Importing this package is cheap; torch is imported by the submodules:

- :mod:`pasta.nn.vae`: :class:`~pasta.nn.vae.PointVAE`, PointNet encoder + folding decoder;
- :mod:`pasta.nn.encoders`: the ``pc_vae`` and ``flat`` :class:`~pasta.core.Encoder` plugins;
- :mod:`pasta.nn.feasibility`: :class:`~pasta.nn.feasibility.SetFeasibility`, one per skill;
- :mod:`pasta.nn.cost`: :class:`~pasta.nn.cost.PairCost` and the ``set_cost`` :class:`~pasta.core.CostModel`;
- :mod:`pasta.nn.loading`: load trained modules from a models directory and attach them to skills;
- the plugin package ``pasta_models`` (``plugins/models``) registers the encoders and the cost model.

Models directory layout (written by ``pasta train``)::

    ROOT/vae/                 model.safetensors + model.json (+ metrics.json, last.*)
    ROOT/feasibility/<skill>/ one set feasibility network per skill
    ROOT/cost/                the pairwise cost network

The Flat 3D baseline has a models root of its own with the same sub-directories (``ROOT/flat`` of a
models root: the shipped ones are ``pasta/weights/flat``; see :mod:`pasta.nn.flat`, loaded by
:func:`pasta.nn.flat.load_flat`)::

    FLAT/vae/                 whole-scene VAE  (pasta train vae data=DIR out=FLAT flat=true)
    FLAT/feasibility/<skill>/ 1 -> 1 scene feasibility (pasta train feasibility ... out=FLAT flat=true skill=S)
    FLAT/cost/                cost of scene pairs (pasta train cost ... out=FLAT flat=true)
"""

#: sub-directory of a models root holding each trained module
VAE_DIR = "vae"
FEASIBILITY_DIR = "feasibility"
COST_DIR = "cost"
#: default models root of the Flat 3D baseline (same sub-directories as an entity root)
FLAT_ROOT = "models/flat"
