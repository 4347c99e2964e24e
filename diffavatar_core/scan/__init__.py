"""Segmented-scan input and preprocessing (docs/scan.md): loading (PLY with per-vertex labels,
OBJ, arrays, ROS message arrays), conversion into the core frame (m, Y up, faces +Z, +X left),
cleaning, garment-region extraction, named boundary loops (openings) and interior samples."""
from .errors import (DegenerateScanError, EmptyScanError, FaceIndexError, ImplausibleSizeError,
                     LabelError, NoGarmentError, NonFiniteError, ScanError, ScanFormatError)
from .frame import ScanTransform
from .labels import OPENING_NAMES, LabelMap
from .loading import RawScan, read_scan_file, scan_from_arrays, scan_from_message
from .preprocess import ScanData, ScanOptions, load_scan, preprocess_scan

__all__ = [
    "ScanData", "ScanOptions", "ScanTransform", "RawScan", "LabelMap", "OPENING_NAMES",
    "load_scan", "preprocess_scan", "read_scan_file", "scan_from_arrays", "scan_from_message",
    "ScanError", "ScanFormatError", "EmptyScanError", "NonFiniteError", "FaceIndexError",
    "LabelError", "NoGarmentError", "DegenerateScanError", "ImplausibleSizeError",
]
