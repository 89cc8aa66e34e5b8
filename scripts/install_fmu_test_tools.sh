#!/usr/bin/env bash
# Install what the cross-platform FMU tests need (the FMU platform tests under tests/):
#   ziglang   C compiler for linux64 (glibc 2.17), win64 and darwin64 (also a test extra)
#   mingw-w64 faster win64 compiler (Debian package)
#   wine      runs the win64 FMU and the C host cross-compiled for Windows (Debian package)
#   qemu-user, libc6-arm64-cross   run the aarch64-linux FMU and C hosts (Debian packages)
#   cmake     fmpy's build_platform_binary (source rebuild test; pip package)
# Each test skips with the reason when its tool is absent. Run as root (apt-get);
# PYTHON defaults to .venv/bin/python. About 2 minutes on a fresh Debian machine.
set -euo pipefail
cd "$(dirname "$0")/.."
PYTHON="${PYTHON:-.venv/bin/python}"
"$PYTHON" -m pip install -q ziglang cmake
if command -v apt-get >/dev/null; then
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -q
    apt-get install -y -q mingw-w64 wine qemu-user libc6-arm64-cross
else
    echo "install_fmu_test_tools: no apt-get here: install mingw-w64, wine and qemu-user with this system's tools" >&2
fi
