"""Segmented-scan input and preprocessing (docs/scan.md): loading (PLY with per-vertex labels,
OBJ, arrays, ROS message arrays), the checks of a scan (check_scan: the cheap ones, which the
ROS node runs at its front door; preprocessing runs them first), conversion into the core frame
(m, Y up, faces +Z, +X left), cleaning, garment-region extraction, named boundary loops
(openings) and interior samples. Every bad scan raises a ScanError subclass whose `code` names
the problem as the ROS interface does (AvatarAssets.ERROR_<code>)."""
from .check import CheckedScan, check_scan, check_template
from .errors import (BadOptionError, DegenerateScanError, EmptyScanError, FaceIndexError,
                     GarmentTypeMissingError, ImplausibleSizeError, LabelError, NoGarmentError,
                     NonFiniteError, ScanError, ScanFormatError, TooLargeError, UnknownGarmentTypeError,
                     UnknownTemplateError, VertexArrayError, all_error_classes)
from .frame import ScanTransform
from .labels import OPENING_NAMES, LabelMap
from .loading import RawScan, read_scan_file, scan_from_arrays, scan_from_message
from .preprocess import ScanData, ScanOptions, load_scan, preprocess_checked, preprocess_scan

__all__ = [
    "ScanData", "ScanOptions", "ScanTransform", "RawScan", "CheckedScan", "LabelMap", "OPENING_NAMES",
    "load_scan", "check_scan", "check_template", "preprocess_scan", "preprocess_checked",
    "read_scan_file", "scan_from_arrays", "scan_from_message",
    "ScanError", "ScanFormatError", "VertexArrayError", "BadOptionError", "TooLargeError",
    "EmptyScanError", "NonFiniteError", "FaceIndexError", "LabelError", "UnknownGarmentTypeError",
    "NoGarmentError", "GarmentTypeMissingError", "UnknownTemplateError", "DegenerateScanError",
    "ImplausibleSizeError", "all_error_classes",
]
