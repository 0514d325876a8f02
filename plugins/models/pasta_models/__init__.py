"""The built-in learned models as plugins: encoders ``pc_vae`` and ``flat``, cost model ``set_cost`` (from pasta.nn)."""
