# Sourced by scripts/test, demo, benchmark, soak, fuzz and package: one place for how the project
# is configured and built.
#   sl_configure DIR [CMAKE_ARGS...]   cmake -G Ninja, ccache as the compiler launcher (when present),
#                                      unity build, line-table debug info (-g1)
#   sl_build DIR [TARGET...]           ninja with a progress line: [done/total elapsed]
# Unity build (batches of 8 files per compile, cmake/SparseloopUnity.cmake; SL_UNITY=OFF turns it
# off): each batch parses the heavy headers (Eigen, OpenCV, Ceres, fmt) once, 1.5x less compile
# time; the batches include their files by relative paths, so ccache serves another clone too. -g1 keeps line tables
# (backtraces, sanitizer reports, perf) without the full debug info, 1.3x less compile time;
# configure a build of your own without these for a debugger session.
# ccache: the cache lives in $CCACHE_DIR (default ~/.cache/ccache) and survives between runs and
# clones on the machine; base_dir + no hash_dir make a clone at another path hit the same entries.
SL_ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
SL_JOBS=${JOBS:-$(nproc)}

if command -v ccache >/dev/null; then
  export CCACHE_DIR=${CCACHE_DIR:-$HOME/.cache/ccache}
  export CCACHE_BASEDIR=$SL_ROOT
  export CCACHE_NOHASHDIR=true
  export CCACHE_MAXSIZE=${CCACHE_MAXSIZE:-12G}
  export CCACHE_COMPRESS=true
  SL_LAUNCHER=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache -DCMAKE_C_COMPILER_LAUNCHER=ccache)
else
  SL_LAUNCHER=()
fi

SL_COMMON=(-DSPARSELOOP_UNITY="${SL_UNITY:-ON}" -DCMAKE_UNITY_BUILD=OFF -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O2 -g1 -DNDEBUG"
  -DCMAKE_CXX_FLAGS_DEBUG="-g1")

sl_configure() {
  local dir=$1
  shift
  mkdir -p "$dir"
  if ! cmake -S "$SL_ROOT" -B "$dir" -G Ninja "${SL_LAUNCHER[@]}" "${SL_COMMON[@]}" "$@" \
      > "$dir/configure.log" 2>&1; then
    echo "configure of $dir failed; the last lines of $dir/configure.log:" >&2
    tail -30 "$dir/configure.log" >&2
    return 1
  fi
}

sl_build() {
  local dir=$1
  shift
  local targets=()
  for t in "$@"; do targets+=(--target "$t"); done
  NINJA_STATUS="[%f/%t %es] " cmake --build "$dir" -j "$SL_JOBS" "${targets[@]}"
}
