#!/usr/bin/env bash
# `make bench`: run every bench/*.py in turn and collect its JSON in out/bench/<name>.json.
#   1. bootstrap the project environment (scripts/bootstrap.sh; a no-op when up to date)
#   2. install the benchmark-only extras (bench/requirements.txt: Newton + Warp, the reference
#      of bench/simulate.py) into .venv, keyed by a hash like the other set-up steps; they are
#      never part of `make setup`. If that install fails the benchmarks still run and
#      bench/simulate.py reports `reference: null` with the reason.
#   3. run each benchmark; its stdout (one JSON document) goes to out/bench/<name>.json, its
#      stderr to out/bench/<name>.log. A failing benchmark is reported and the others still run;
#      the script exits non-zero at the end if any failed.
# Usage: scripts/bench.sh [NAME ...] [-- ARGS passed to every benchmark, e.g. --quick]
#   BENCH_THREADS (default: nproc) sets the thread count of the benchmarks that take --threads.
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$(pwd)
VENV=$ROOT/.venv
STAMPS=$VENV/.stamps
OUT=$ROOT/out/bench
say() { printf '[bench] %s\n' "$*"; }
hash_of() { cat "$@" | sha256sum | cut -c1-16; }

names=()
extra=()
while [ $# -gt 0 ]; do
  if [ "$1" = "--" ]; then shift; extra=("$@"); break; fi
  names+=("$1"); shift
done

scripts/bootstrap.sh

bench_hash=$(hash_of bench/requirements.txt constraints.txt)
if [ ! -f "$STAMPS/bench" ] || [ "$(cat "$STAMPS/bench")" != "$bench_hash" ]; then
  say "installing benchmark-only extras (bench/requirements.txt; Warp is a ~150 MB wheel)"
  if "$VENV/bin/python" -m pip install --quiet --disable-pip-version-check \
       -r bench/requirements.txt -c constraints.txt; then
    mkdir -p "$STAMPS"; echo "$bench_hash" > "$STAMPS/bench"
  else
    say "WARNING: installing bench/requirements.txt failed; benchmarks needing it report no reference"
  fi
fi

mkdir -p "$OUT"
if [ ${#names[@]} -eq 0 ]; then
  for f in bench/*.py; do n=$(basename "$f" .py); [[ $n == _* ]] || names+=("$n"); done   # _*.py: helpers
fi
failed=()
for name in "${names[@]}"; do
  f=bench/$name.py
  [ -f "$f" ] || { say "no such benchmark: $f"; failed+=("$name"); continue; }
  args=("${extra[@]}")
  if grep -q -- '--threads' "$f"; then args+=(--threads "${BENCH_THREADS:-$(nproc)}"); fi
  say "running $f ${args[*]}"
  t0=$(date +%s)
  if "$VENV/bin/python" "$f" "${args[@]}" > "$OUT/$name.json.tmp" 2> "$OUT/$name.log"; then
    mv "$OUT/$name.json.tmp" "$OUT/$name.json"
    say "$name done in $(( $(date +%s) - t0 )) s -> out/bench/$name.json"
  else
    rm -f "$OUT/$name.json.tmp"
    say "$name FAILED after $(( $(date +%s) - t0 )) s (log: out/bench/$name.log)"; tail -20 "$OUT/$name.log" || true
    failed+=("$name")
  fi
done
if [ ${#failed[@]} -gt 0 ]; then say "failed: ${failed[*]}"; exit 1; fi
say "all done: $(ls "$OUT"/*.json | xargs -n1 basename | xargs)"
