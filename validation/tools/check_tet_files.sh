#!/usr/bin/env bash
# Read ergohand's tetrahedral files with independent readers (meshio, and the Gmsh SDK for
# .msh) and fail unless counts, volumes, the boundary and the named groups check out (see
# check_tet_files.py). Installs meshio, numpy and gmsh from PyPI into a venv under target/,
# and the Debian libraries the gmsh wheel links against when it cannot be imported.
# Usage: bash validation/tools/check_tet_files.sh FILE.vtk|FILE.msh ...
set -euo pipefail
cd "$(dirname "$0")/../.."
[ $# -gt 0 ] || { echo "usage: check_tet_files.sh FILE.vtk|FILE.msh ..." >&2; exit 2; }
venv=${TET_CHECK_VENV:-target/tet-check-venv}
if [ ! -x "$venv/bin/python" ]; then
  python3 -m venv "$venv"
fi
if ! "$venv/bin/python" -c "import meshio, numpy, gmsh" 2>/dev/null; then
  "$venv/bin/pip" install --quiet --disable-pip-version-check meshio==5.3.5 numpy gmsh==4.15.2 || true
fi
if ! "$venv/bin/python" -c "import gmsh" 2>/dev/null; then
  echo "check_tet_files: installing the libraries the gmsh wheel needs (apt-get)" >&2
  SUDO=""
  if [ "$(id -u)" != 0 ] && command -v sudo >/dev/null 2>&1; then SUDO=sudo; fi
  $SUDO apt-get update -qq >&2
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq \
    libglu1-mesa libxcursor1 libxinerama1 libxft2 libxrender1 libgomp1 >&2
fi
"$venv/bin/python" validation/tools/check_tet_files.py "$@"
