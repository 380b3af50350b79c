#!/usr/bin/env bash
# Install loosefit into ./.venv (idempotent). Used by `make`, the README and .ci/run.
#
# PyTorch: a pinned CPU build is taken when pip can find it (this project's
# machines keep torch 2.13.0+cpu in a local wheel folder); elsewhere pip's own
# choice of torch is installed. Set TORCH_SPEC to force one, e.g.
#   TORCH_SPEC="torch==2.13.0 --index-url https://download.pytorch.org/whl/cpu"
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-python3}

# Headless OpenGL (EGL + Mesa's software rasteriser) for `loosefit render`.
if ! ldconfig -p 2>/dev/null | grep -q 'libEGL_mesa'; then
  if command -v apt-get >/dev/null && [ "$(id -u)" = 0 ]; then
    echo "installing EGL/Mesa system libraries for offscreen rendering"
    apt-get update -qq >/dev/null
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq \
      libegl1 libgl1 libegl-mesa0 libgl1-mesa-dri >/dev/null
  else
    echo "note: EGL/Mesa not found; rendering needs e.g. 'apt-get install libegl1 libgl1 libegl-mesa0 libgl1-mesa-dri'" >&2
  fi
fi

if [ ! -x .venv/bin/python ]; then
  "$PY" -m venv .venv
fi
VPY=.venv/bin/python
if ! $VPY -c "import torch" 2>/dev/null; then
  if [ -n "${TORCH_SPEC:-}" ]; then
    # shellcheck disable=SC2086
    $VPY -m pip install -q $TORCH_SPEC
  else
    $VPY -m pip install -q "torch==2.13.0" 2>/dev/null || $VPY -m pip install -q torch
  fi
fi
# The optional extras too, so that `make test` runs their tests (viewer, cluster, onnx).
$VPY -m pip install -q -e ".[dev,viewer,cluster,onnx,alembic]"
# Blender as a Python module, for the tests that open each export in Blender
# (tests/export/test_blender_read.py; they skip where it is absent). Its wheel pins
# numpy<2, which Blender's importers do not need: installed without its
# dependencies so that it leaves loosefit's numpy as it is. LOOSEFIT_NO_BPY=1 skips it.
if [ -z "${LOOSEFIT_NO_BPY:-}" ] && ! $VPY -c "import importlib.util as u, sys; sys.exit(u.find_spec('bpy') is None)" 2>/dev/null; then
  $VPY -m pip install -q --no-deps "bpy==5.0.1" || echo "note: bpy (Blender) did not install; the Blender checks will skip" >&2
fi
$VPY -c "import torch, loosefit; print(f'loosefit {loosefit.__version__} installed (torch {torch.__version__})')"
