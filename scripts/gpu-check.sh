#!/usr/bin/env bash
# Conformance tests and benches on a lent GPU machine that has no Rust
# toolchain: the test binaries, the Embree bench, `afs` and the reuse
# example, built here and packed with the Vulkan loader, the validation
# layer, Embree and the shared models by scripts/gpu-bundle.sh.
#
#   bash scripts/gpu-check.sh BUNDLE.tar.xz OUTDIR [SECONDS] [STAGES]
#
# STAGES (default all): tests bench modes sizes reuse random. Each stage
# stops early when the SECONDS budget (default 420) runs low; the summary
# is OUTDIR/summary.txt.
set -u
bundle=$1 out=$2 budget=${3:-420} stages=${4:-"tests bench modes sizes reuse random"}
t0=$(date +%s)
left() { echo $((budget - ($(date +%s) - t0))); }
want() { [[ " $stages " == *" $1 "* ]]; }
B=/tmp/afs-gpu
mkdir -p "$B" "$out"
S=$out/summary.txt
# The Vulkan loader and glvnd (the NVIDIA ICD needs libGLdispatch), as debs.
for f in .gl/*.deb; do dpkg -x "$f" /; done
ldconfig
python3 -c "import tarfile,sys; tarfile.open(sys.argv[1]).extractall(sys.argv[2])" "$bundle" "$B"
export LD_LIBRARY_PATH=$B/lib VK_LAYER_PATH=$B/layers XDG_RUNTIME_DIR=/tmp HOME=/tmp
icd=$(ls /usr/local/nvidia/share/vulkan/icd.d/*.json /usr/share/vulkan/icd.d/nvidia*.json 2>/dev/null | head -1)
[ -n "$icd" ] && export VK_ICD_FILENAMES=$icd VK_DRIVER_FILES=$icd
# The binaries were built in /work/main (CARGO_MANIFEST_DIR) beside
# /work/shared; the cli tests run target/release/afs.
mkdir -p /work /work/shared target/release
[ -e /work/main ] || ln -s "$PWD" /work/main
[ -e /work/shared/assets ] || ln -s "$B/assets" /work/shared/assets
cp "$B/bin/afs" target/release/afs
{ echo "icd: $icd"; nvidia-smi -L; echo "cores: $(nproc)"; "$B/bin/afs" info; } > "$out/devices.txt" 2>&1
cat "$out/devices.txt" >> "$S"
if ! "$B/bin/afs" info > /dev/null 2>&1; then
  VK_LOADER_DEBUG=error,warn,info "$B/bin/afs" info 2>&1 | tail -60 >> "$S"
  exit 1
fi

if want tests; then
  echo "== tests ($(left) s left)" >> "$S"
  # Six test binaries at a time; a failing one's panics are kept.
  export B out
  ls "$B"/tests/* | grep -v random_conformance | xargs -P 6 -I{} bash -c '
    n=$(basename {}); s=$(date +%s)
    timeout 200 {} > "$out/t-$n.log" 2>&1; rc=$?
    echo "$n rc=$rc $(( $(date +%s) - s ))s $(grep "test result" "$out/t-$n.log" | tail -1)" >> "$out/summary.txt"
    if [ $rc -ne 0 ]; then
      { echo "--- $n rc=$rc"
        grep -E "pixel \(|disagree|differ" "$out/t-$n.log" | head -20 | cut -c1-600
        grep -A12 "panicked at" "$out/t-$n.log" | grep -v "^stack backtrace\|^note:\|^ *[0-9]*: \|^ *at " | cut -c1-1500
      } >> "$out/tests.log"
    fi
    rm -f "$out/t-$n.log"'
fi

if want bench; then
  echo "== embree bench ($(left) s left)" >> "$S"
  CARGO_TARGET_DIR=$out timeout $(($(left) - 60)) "$B/bin/embree" --bench > "$out/bench.log" 2>&1
  echo "embree rc=$?" >> "$S"
  grep -E 'ours/Embree|panicked' "$out/bench.log" >> "$S"
fi

R=$out/runs.log
run() {
  [ "$(left)" -gt 40 ] || return
  echo "### $*" >> "$R"
  timeout 60 "$B/bin/afs" render "$@" --stats --quiet -o /tmp/r.png >> "$R" 2>&1
  echo "rc=$?" >> "$R"
}
toy=/work/shared/assets/ToyCar/ToyCar.gltf
if want modes; then
  echo "== modes ($(left) s left)" >> "$S"
  for sc in builtin:demo builtin:torus_knot:20000 "$toy --ground"; do
    for n in 128 1024; do
      for m in lut exact approx; do
        # shellcheck disable=SC2086
        run $sc --light sphere --samples $n --mode $m --width 512 --height 512 --repeat 3
      done
    done
  done
fi
if want sizes; then
  echo "== sizes ($(left) s left)" >> "$S"
  for sz in 1024 2048; do
    for l in point sphere; do
      run builtin:torus_knot:100000 --light $l --samples 128 --width $sz --height $sz --repeat 3
      run "$toy" --ground --light $l --samples 128 --width $sz --height $sz --repeat 3
    done
  done
fi
if [ -s "$R" ]; then
  # One line per run: frame total, the light's wall and GPU time, host time.
  python3 - "$R" >> "$S" <<'PY'
import json, sys
for block in open(sys.argv[1]).read().split("### ")[1:]:
    head = block.split("\n")[0].replace("/work/shared/assets/", "")
    try:
        d = json.loads(block[block.index("{"):block.rindex("}") + 1])
        l = d["lights"][0]["stats"]
        print(f"{head[:70]:70} total {d['total_ms']:7.1f} light {l['wall_ms']:7.1f} "
              f"gpu {l['gpu_ms']:7.1f} inputs {d['ms'].get('inputs_cpu', 0):5.1f} "
              f"shade {d['ms']['shade_cpu']:5.1f} ranges {l.get('unsure_ranges', 0)}")
    except (ValueError, KeyError) as e:
        print(f"{head[:70]:70} no stats ({e})")
PY
fi
if want reuse; then
  echo "== reuse ($(left) s left)" >> "$S"
  timeout 60 "$B/bin/reuse" "$toy" 512 3 2>&1 | tail -40 >> "$S"
fi
if want random && [ "$(left)" -gt 30 ]; then
  echo "== random 3000 ($(left) s left)" >> "$S"
  AFS_RANDOM_CASES=3000 AFS_RANDOM_SEED=7 timeout $(($(left) - 10)) \
    "$B/tests/random_conformance" --nocapture > "$out/random.log" 2>&1
  echo "random rc=$?" >> "$S"
  tail -15 "$out/random.log" >> "$S"
fi
echo "== done at $(($(date +%s) - t0)) s" >> "$S"
