"""XPBD cloth simulation (paper §3.2): build a garment from arrays, step it, drape it on a body.

Units: metres, kilograms, seconds. The C++ solver is in cpp/sim/; this package validates.
"""
from .cloth import Cloth, DrapeResult, SimulationDiverged
from .material import ClothMaterial

__all__ = ["Cloth", "ClothMaterial", "DrapeResult", "SimulationDiverged"]
