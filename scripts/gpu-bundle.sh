#!/usr/bin/env bash
# Packs what scripts/gpu-check.sh runs on a GPU machine without Rust: the
# release test binaries, the Embree bench, `afs`, the reuse example, the
# Vulkan loader, the validation layer, Embree and TBB, and the shared
# models, stripped and xz-compressed (about 55 MB).
#
#   bash scripts/gpu-bundle.sh OUT.tar.xz
set -euo pipefail
out=$(realpath -m "$1")
cd "$(dirname "$0")/.."
stage=$(mktemp -d)
mkdir -p "$stage"/{bin,tests,lib,layers,assets}
list() { cargo "$@" --no-run --features embree --message-format=json 2>/dev/null; }
{ list test --release; list bench; } | python3 -c '
import json, subprocess, sys
stage = sys.argv[1]
for line in sys.stdin:
    try:
        d = json.loads(line)
    except ValueError:
        continue
    if d.get("reason") != "compiler-artifact" or not d.get("executable") or not d["profile"]["test"]:
        continue
    kind, name = d["target"]["kind"][0], d["target"]["name"]
    if kind == "bench":
        if name != "embree":
            continue
        dst = stage + "/bin/embree"
    else:
        dst = stage + "/tests/" + (name if kind == "test" else "unit_" + name)
    subprocess.run(["strip", "-o", dst, d["executable"]], check=True)
' "$stage"
cargo build --release --features embree --bin afs --example reuse
strip -o "$stage/bin/afs" target/release/afs
strip -o "$stage/bin/reuse" target/release/examples/reuse
lib=/usr/lib/x86_64-linux-gnu
cp -L "$lib"/{libvulkan.so.1,libembree3.so.3,libtbb.so.12,libtbbmalloc.so.2,libVkLayer_khronos_validation.so} "$stage/lib/"
cp /usr/share/vulkan/explicit_layer.d/VkLayer_khronos_validation.json "$stage/layers/"
[ -d ../shared/assets ] && cp -r ../shared/assets/. "$stage/assets/"
tar -C "$stage" -cf - . | xz -T0 -6 > "$out"
rm -rf "$stage"
ls -la "$out"
