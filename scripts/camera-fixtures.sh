#!/usr/bin/env bash
# Regenerates tests/data/cameras with pycolmap (COLMAP's own Python bindings)
# and OpenCV: sparse models in text and binary, pycolmap's and OpenCV's
# projections of points, and the same cameras as a nerfstudio transforms.json. Run from the repository root.
set -euo pipefail
venv=$(mktemp -d)
trap 'rm -rf "$venv"' EXIT
python3 -m venv "$venv"
"$venv/bin/pip" install -q pycolmap==4.2.1 opencv-python-headless==5.0.0.93
rm -rf tests/data/cameras/colmap tests/data/cameras/colmap_distorted
"$venv/bin/python" tests/data/cameras/make_fixtures.py tests/data/cameras
