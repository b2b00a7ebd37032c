#!/usr/bin/env bash
# Installs the Debian packages the project needs (run as root):
# lavapipe (Mesa's CPU Vulkan driver), the Vulkan loader and validation
# layers, and the C++ toolchain that builds shaderc from source.
set -euo pipefail
cd "$(dirname "$0")/.."
export DEBIAN_FRONTEND=noninteractive
apt-get update
# shellcheck disable=SC2046
apt-get install -y --no-install-recommends $(grep -v '^#' scripts/packages.txt)
if ! command -v cargo >/dev/null 2>&1; then
    echo "error: cargo not found: install a Rust toolchain (https://rustup.rs) first" >&2
    exit 1
fi
