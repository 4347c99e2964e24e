"""Simulation-ready proof (paper §5.5): the garment simulated on the body in novel motions."""
from .motions import MOTIONS, load_keyframes, motion_pose
from .simulate import AnimationResult, animate

__all__ = ["MOTIONS", "load_keyframes", "motion_pose", "animate", "AnimationResult"]
