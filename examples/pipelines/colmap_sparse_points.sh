#!/usr/bin/env bash
# The point-cloud variant of colmap_sparse_poisson.sh: the same features, matching and
# triangulation with the known poses, but no surface: the model is OUT_DIR/points.ply (coloured
# points with normals; rephoto renders them as splats sized from the local point density).
# Usage: colmap_sparse_points.sh [options] SPARSE_DIR IMAGE_DIR OUT_DIR [THREADS]
#   (options as colmap_sparse_poisson.sh: --max-image-size, --max-features, --matcher,
#    --neighbors, --two-view-tracks, --keep-work)
# Needs: colmap, python3-numpy, python3-scipy.
set -euo pipefail
exec "$(dirname "${BASH_SOURCE[0]}")/colmap_sparse_poisson.sh" --mesher none "$@"
