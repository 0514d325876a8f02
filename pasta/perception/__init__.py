"""Real depth-camera clouds for ``pasta plan``: reading files (``.npy``, organised clouds, ascii and binary
PLY), the input frame (units, up axis, camera-to-workspace transform) and preprocessing (crop, table
removal, outlier removal, completion of top-down views). See ``docs/real_world.md``.

Numpy, scipy and scikit-learn only; nothing here imports torch.
"""

from pasta.perception.clouds import CloudFrame, LoadedCloud, read_cloud, read_ply, read_transform
from pasta.perception.preprocess import PRESETS, TABLE_HEIGHT, PreprocessConfig, Preprocessed, preprocess

__all__ = ["CloudFrame", "LoadedCloud", "PRESETS", "PreprocessConfig", "Preprocessed", "TABLE_HEIGHT", "preprocess",
           "read_cloud", "read_ply", "read_transform"]
