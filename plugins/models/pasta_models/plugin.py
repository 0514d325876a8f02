"""Entry-point module of the learned plugins: encoders ``pc_vae`` and ``flat``, cost model ``set_cost``.

Only config dataclasses are imported here; the torch networks load when a plugin is built.
"""

from pasta.nn.config import FlatEncoderConfig, PointVAEEncoderConfig, SetCostConfig
from pasta.plugins import hookimpl


@hookimpl
def pasta_register_encoders(register):
    register(name="pc_vae", factory="pasta.nn.encoders:PointVAEEncoder", config=PointVAEEncoderConfig,
             summary="PointNet VAE of one centred entity, u = [z, centroid]")
    register(name="flat", factory="pasta.nn.encoders:FlatEncoder", config=FlatEncoderConfig,
             summary="the whole dough cloud as one latent (Flat 3D baseline)")


@hookimpl
def pasta_register_cost_models(register):
    register(name="set_cost", factory="pasta.nn.cost:SetCostModel", config=SetCostConfig,
             summary="pairwise network predicting entity Chamfer distance; min over matchings")
