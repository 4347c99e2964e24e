"""Errors of the scan loader and preprocessing. Every one is a ValueError (the CLI and the ROS
node report ValueErrors as bad input), and its message names the problem and, where it helps,
what to change (units, up axis, label)."""
from __future__ import annotations


class ScanError(ValueError):
    """Base class: the scan cannot be used as given."""


class ScanFormatError(ScanError):
    """The file cannot be read as a triangle mesh, or an option (units, up axis) is unknown."""


class EmptyScanError(ScanError):
    """The scan has no vertices or no triangles (before or after cleaning)."""


class NonFiniteError(ScanError):
    """Some vertex coordinates are NaN or Inf."""


class FaceIndexError(ScanError):
    """A face refers to a vertex index outside [0, #V), or faces are not integer triangles."""


class LabelError(ScanError):
    """Per-vertex labels are malformed (wrong length, not integers) or a label name is unknown."""


class NoGarmentError(ScanError):
    """No vertex (or no whole triangle) carries the requested garment label, or the garment
    cannot be chosen from the labels present."""


class DegenerateScanError(ScanError):
    """The surface (or the garment region) has zero area once degenerate triangles are removed."""


class ImplausibleSizeError(ScanError):
    """The scan's height in metres is outside the range of a person or garment
    (usually wrong units or up axis)."""
