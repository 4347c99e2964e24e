"""Point the ROS 2 wheels' exported CMake files at this interpreter (idempotent).

The Jazzy PyPI wheels were built where Python lived at /opt/python/cp311-cp311; every message
package's exported CMake still names that interpreter's include dir and numpy's include dir,
so CMake fails with "includes non-existent path" when another package (ours) builds
interfaces against them. See shared/notes/ros2-jazzy-from-pypi.md, pitfall 1.
Usage: python fix_ros_cmake_paths.py PREFIX   (PREFIX = the virtualenv)
"""
import pathlib
import sys
import sysconfig

import numpy

BUILD_PREFIX = "/opt/python/cp311-cp311"
REPLACEMENTS = {
    BUILD_PREFIX + "/lib/python3.11/site-packages/numpy/_core/include": numpy.get_include(),
    BUILD_PREFIX + "/include/python3.11": sysconfig.get_paths()["include"],
}


def main(prefix: str) -> int:
    changed = 0
    for path in pathlib.Path(prefix, "share").rglob("*.cmake"):
        text = path.read_text(encoding="utf-8", errors="surrogateescape")
        if BUILD_PREFIX not in text:
            continue
        for old, new in REPLACEMENTS.items():
            text = text.replace(old, new)
        path.write_text(text, encoding="utf-8", errors="surrogateescape")
        changed += 1
    print(f"fix_ros_cmake_paths: rewrote {changed} file(s) under {prefix}/share")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
