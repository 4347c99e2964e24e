"""The DiffAvatar recovery pipeline (paper §4): segmented scan in, co-optimized pattern,
material and body out. recover() is the main job (pipeline/recovery.py)."""
from .options import RecoverOptions
from .recovery import RecoveryCancelled, RecoveryError, recover

__all__ = ["recover", "RecoverOptions", "RecoveryError", "RecoveryCancelled"]
