"""The DiffAvatar recovery pipeline (paper §4): segmented scan in, co-optimized pattern,
material and body out."""
