#!/usr/bin/env bash
# Instructions of one warm frame on lavapipe, counted by valgrind: a
# measure that this 2-core machine's noise (frame times moving by 5-25%
# between runs of the same binary) does not touch, for comparing two
# builds of a pass whose difference is a few percent.
#
#   scripts/frame-instructions.sh [AFS_BINARY] -- RENDER_ARGS...
#   scripts/frame-instructions.sh target/release/afs -- builtin:torus_knot:20000 \
#       --light sphere --width 256 --height 256
#
# It runs `afs render RENDER_ARGS --repeat 2` and `--repeat 3` under
# cachegrind (the two at once, one per core) and prints the differences:
# the instructions of the third frame, a warm one, in lavapipe's compiled
# shaders (code in no mapped file, cachegrind's `???:???`) and in all.
# LP_NUM_THREADS=0 makes lavapipe run every workgroup on the submitting
# thread, in order. The shaders' count repeats between runs of one binary
# (torus_knot:20000 at 256², three frames: 24,846.7 M and 24,845.1 M
# instructions in the shaders) where the whole run's moves by 69 M (LLVM's
# compilation and the waits vary), so compare the shaders' counts. Instructions are not time (lavapipe's
# gathers and cache misses cost more than their count), but where the
# pass is compute-bound they follow it: look-up over approximate mode on
# `torus_knot:20000` at 256², 1.44 in shader instructions against
# 1.33-1.39 in single-thread frame times at 512² (docs/status.md, stop
# 55).
# A 256² frame takes 2-4 minutes under valgrind. Needs valgrind (Debian:
# `apt-get install valgrind`).
set -euo pipefail
bin=target/release/afs
if [[ $# -gt 0 && $1 != "--" ]]; then
    bin=$1
    shift
fi
if [[ $# -eq 0 || $1 != "--" ]]; then
    sed -n '2,/^set -e/p' "$0" | sed '$d' | sed 's/^# \{0,1\}//'
    exit 2
fi
shift
command -v valgrind >/dev/null || { echo "valgrind is not installed (apt-get install valgrind)" >&2; exit 1; }
[[ -x $bin ]] || { echo "no afs binary at $bin (cargo build --release)" >&2; exit 1; }
bin=$(realpath "$bin")
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
export XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-/tmp}
count() {
    MESA_SHADER_CACHE_DISABLE=true LP_NUM_THREADS=0 valgrind --tool=cachegrind --cache-sim=no \
        --cachegrind-out-file="$work/cg.$1.out" "$bin" render "${@:2}" --repeat "$1" --quiet \
        -o "$work/image.$1.png" >"$work/log.$1" 2>&1 || { cat "$work/log.$1" >&2; return 1; }
    grep -oE 'I +refs: +[0-9,]+' "$work/log.$1" | tr -d ', ' | cut -d: -f2 >"$work/ir.$1"
    cg_annotate "$work/cg.$1.out" | grep -E '^ *[0-9,]+ \([ 0-9.]+%\)  \?\?\?:\?\?\?$' \
        | awk '{gsub(",", "", $1); print $1}' >"$work/jit.$1"
}
count 2 "$@" &
two=$!
count 3 "$@"
wait "$two"
a=$(cat "$work/ir.2")
b=$(cat "$work/ir.3")
ja=$(cat "$work/jit.2")
jb=$(cat "$work/jit.3")
echo "instructions of one warm frame: shaders $((jb - ja)), all $((b - a))"
echo "(runs of 2 and 3 frames: shaders $ja, $jb; all $a, $b)"
