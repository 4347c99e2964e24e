"""Errors of the scan loader, checks and preprocessing: the one definition of what makes a scan
unusable, for the CLI, the recovery pipeline and the ROS node alike.

Every one is a ValueError whose message names the problem and, where it helps, what to change
(units, up axis, label). Every class also carries `code`, the name of the problem as the ROS
interface spells it (`AvatarAssets.ERROR_<code>`), so a caller maps the class to its own status
without parsing text (the node answers `ERROR_<code>` with the message as `error_msg`)."""
from __future__ import annotations


class ScanError(ValueError):
    """Base class: the scan cannot be used as given."""
    code = "BAD_OPTION"


class ScanFormatError(ScanError):
    """The file cannot be read as a triangle mesh, or an option (units, up axis) is unknown."""
    code = "BAD_VERTEX_ARRAY"


class VertexArrayError(ScanFormatError):
    """The vertex array is not (N, 3) or flat (3N,), or not numbers."""
    code = "BAD_VERTEX_ARRAY"


class BadOptionError(ScanFormatError):
    """An option of the scan is unknown: units (m, cm, mm) or up axis (y, z)."""
    code = "BAD_OPTION"


class TooLargeError(ScanError):
    """The scan has more vertices than the caller's limit (the node's `max_vertices`)."""
    code = "TOO_LARGE"


class EmptyScanError(ScanError):
    """The scan has no vertices or no triangles (before or after cleaning)."""
    code = "EMPTY_MESH"


class NonFiniteError(ScanError):
    """Some vertex coordinates are NaN or Inf, or of a magnitude no scan has (≥ 1e100 scan
    units: garbage, whose squared distances would overflow)."""
    code = "NON_FINITE"


class FaceIndexError(ScanError):
    """A face refers to a vertex index outside [0, #V), or faces are not integer triangles (a PLY
    face of fewer than 3 vertices: an edge or point stored as a face)."""
    code = "BAD_FACE_INDEX"


class LabelError(ScanError):
    """Per-vertex (or a PLY's per-face) labels are malformed (wrong length, not integers, out of
    a class value's range, a value naming no class of the scan's label_names, per-vertex and
    per-face labels that disagree, values the label map does not name on a sizeable part of the
    scan), or a label name is unknown or not a garment."""
    code = "BAD_LABELS"


class UnknownGarmentTypeError(LabelError):
    """The garment type given is not in the label map (config/labels.yaml)."""
    code = "UNKNOWN_GARMENT_TYPE"


class NoGarmentError(ScanError):
    """No vertex (or no whole triangle) carries the requested garment label, or the garment
    cannot be chosen from the labels present."""
    code = "NO_GARMENT"


class GarmentTypeMissingError(NoGarmentError, UnknownGarmentTypeError):
    """The garment type is needed but not given: a garment-only scan (no labels), or labels
    whose names are neither a garment class or type nor a known non-garment class."""
    code = "UNKNOWN_GARMENT_TYPE"


class UnknownTemplateError(ScanError):
    """The template asked for is neither an existing template file nor a known built-in name."""
    code = "UNKNOWN_TEMPLATE"


class ImplausibleSizeError(ScanError):
    """The scan's height in metres is outside the range of a person or garment
    (usually wrong units or up axis)."""
    code = "IMPLAUSIBLE_SIZE"


class DegenerateScanError(ScanError):
    """The surface (or the garment region) has zero area once degenerate triangles are removed,
    or a negligible total area for its extent (all triangles collinear or collapsed). The ROS
    interface has no code of its own for it: the surface has an implausible size."""
    code = "IMPLAUSIBLE_SIZE"


def all_error_classes() -> list[type[ScanError]]:
    """ScanError and every subclass (recursively), each once."""
    out, todo = [], [ScanError]
    while todo:
        cls = todo.pop(0)
        if cls not in out:
            out.append(cls)
            todo.extend(cls.__subclasses__())
    return out
