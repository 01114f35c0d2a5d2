#!/usr/bin/env bash
# Tests deepcontact-onnx on real ONNX Runtime: the libonnxruntime.so shipped in the PyPI
# `onnxruntime` wheel, loaded at run time through ort's `load-dynamic` feature.
# Usage: bash .ci/onnxruntime.sh   (from the repository root; needs python3 and PyPI)
set -euo pipefail
cd "$(dirname "$0")/.."

venv=target/ort-venv
if [ ! -x "$venv/bin/python" ]; then
    python3 -m venv "$venv"
fi
"$venv/bin/python" -m pip install --quiet --disable-pip-version-check "onnxruntime>=1.24"

capi=$("$venv/bin/python" -c 'import onnxruntime, os; print(os.path.join(os.path.dirname(onnxruntime.__file__), "capi"))')
lib=$(find "$capi" -maxdepth 1 -name 'libonnxruntime.so*' -type f | sort | head -n 1)
if [ -z "$lib" ]; then
    echo "error: no libonnxruntime.so* in $capi" >&2
    exit 1
fi
echo "ONNX Runtime library: $lib"

# ort's alternative-backend API (the default `tract` feature) replaces its dynamic loader,
# so the ONNX Runtime build is the crate without default features.
ORT_DYLIB_PATH="$(realpath "$lib")" cargo test --release -p deepcontact-onnx --no-default-features --features load-dynamic
