#!/usr/bin/env bash
# A CPU reconstruction from KNOWN cameras with Debian's colmap (no CUDA needed):
#   1. SIFT features of the training photos listed in SPARSE_DIR/images.txt only
#      (colmap feature_extractor; other photos in IMAGE_DIR, e.g. test photos, are never read);
#   2. matching: exhaustive up to 40 images, else each image with its nearest cameras that look
#      the same way (pairs chosen from the known poses; colmap matches_importer);
#   3. triangulation with the known poses and intrinsics, which stay fixed
#      (colmap point_triangulator; database ids and cameras are made to agree with the model);
#   4. OUT_DIR/points.ply: the triangulated points with colours and normals oriented towards the
#      cameras that saw them (a point-cloud model);
#   5. OUT_DIR/mesh.ply: screened Poisson surface of those points, trimmed where the point
#      density is low, and subdivided so that vertex colours can hold detail (no colours: run
#      `rephoto colorize` or `rephoto evaluate --colorize`).
#
# Usage: colmap_sparse_poisson.sh [options] SPARSE_DIR IMAGE_DIR OUT_DIR [THREADS]
#   SPARSE_DIR  COLMAP text model (cameras.txt, images.txt with the poses; points3D.txt ignored)
#   IMAGE_DIR   folder the names in images.txt are relative to
#   OUT_DIR     output folder (created)
#   THREADS     CPU threads (default: all cores)
# Options:
#   --max-image-size N   SIFT on photos scaled so the longer side is at most N px (default 1600;
#                        0 = full size); keypoints stay in full-size pixels
#   --max-features N     SIFT features per photo (default 8192)
#   --matcher M          auto | exhaustive | poses (default auto: exhaustive up to 40 images)
#   --neighbors K        poses matcher: partners per image (default 20)
#   --mesher M           open3d (default) | colmap (colmap poisson_mesher) | none (points only)
#   --depth D            Poisson octree depth, or auto (default): finest cell about the median
#                        distance between neighbouring points, at most 11
#   --trim Q             open3d: drop vertices below the Q-quantile of density (default 0.1);
#                        colmap: PoissonRecon trim value (default depth - 3; its density
#                        values run up to about depth - 0.5)
#   --subdivide S        midpoint subdivisions of the mesh, or auto (default: edges of about
#                        --target-pixels full-size photo pixels, at most 2M triangles)
#   --target-pixels P    (default 4)
#   --two-view-tracks B  1 (default): keep points seen by only two photos; 0: COLMAP's default
#                        of dropping them (fewer, surer points, a smaller scene box; nothing at
#                        all from two photos)
#   --keep-work          keep OUT_DIR/work (the COLMAP database; about 1.5 MB per photo)
# Writes OUT_DIR/points.ply, OUT_DIR/mesh.ply (unless --mesher none), OUT_DIR/sparse/ (the
# triangulated COLMAP text model), OUT_DIR/pipeline.log (the time of each step) and
# OUT_DIR/logs/<step>.log (each tool's output). Exit code 0 on success, 1 on any failure, with a
# one-line message naming the failed step or the missing tool.
# Needs: colmap, python3-numpy, python3-scipy, and python3-open3d unless --mesher none
# (examples/pipelines/install-deps.sh installs them).
set -euo pipefail

here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
prog=$(basename "$0")
die() { echo "$prog: error: $*" >&2; exit 1; }
usage() { sed -n '/^# Usage:/,/^set -euo/p' "$0" | sed '$d; s/^# \{0,1\}//' >&2; exit 1; }

max_image_size=1600 max_features=8192 matcher=auto neighbors=20 mesher=open3d depth=auto
trim="" subdivide=auto target_pixels=4 keep_work=0 two_view_tracks=1
positional=()
while [ $# -gt 0 ]; do
  case "$1" in
    --max-image-size) max_image_size=${2:?}; shift 2 ;;
    --max-features) max_features=${2:?}; shift 2 ;;
    --matcher) matcher=${2:?}; shift 2 ;;
    --neighbors) neighbors=${2:?}; shift 2 ;;
    --mesher) mesher=${2:?}; shift 2 ;;
    --depth) depth=${2:?}; shift 2 ;;
    --trim) trim=${2:?}; shift 2 ;;
    --subdivide) subdivide=${2:?}; shift 2 ;;
    --target-pixels) target_pixels=${2:?}; shift 2 ;;
    --two-view-tracks) two_view_tracks=${2:?}; shift 2 ;;
    --keep-work) keep_work=1; shift ;;
    -h|--help) usage ;;
    --*) die "unknown option $1 (see --help)" ;;
    *) positional+=("$1"); shift ;;
  esac
done
[ ${#positional[@]} -ge 3 ] && [ ${#positional[@]} -le 4 ] || usage
sparse=${positional[0]} images=${positional[1]} out=${positional[2]}
threads=${positional[3]:-$(nproc)}
case "$matcher" in auto|exhaustive|poses) ;; *) die "--matcher must be auto, exhaustive or poses" ;; esac
case "$mesher" in open3d|colmap|none) ;; *) die "--mesher must be open3d, colmap or none" ;; esac
case "$two_view_tracks" in 0|1) ;; *) die "--two-view-tracks must be 0 or 1" ;; esac
[[ "$threads" =~ ^[1-9][0-9]*$ ]] || die "THREADS must be a positive integer, got '$threads'"
[ -f "$sparse/cameras.txt" ] && [ -f "$sparse/images.txt" ] ||
  die "$sparse: no cameras.txt/images.txt (expected a COLMAP text model)"
[ -d "$images" ] || die "$images: no such image folder"

# Tools, each named with the Debian package that provides it.
python=/usr/bin/python3
command -v colmap >/dev/null || die "colmap not found: install the Debian package colmap"
[ -x "$python" ] || die "$python not found: install the Debian package python3"
"$python" -c "import numpy, scipy" 2>/dev/null ||
  die "Python modules numpy/scipy not found: install python3-numpy python3-scipy"
if [ "$mesher" != none ]; then
  "$python" -c "import open3d" 2>/dev/null ||
    die "Python module open3d not found: install the Debian package python3-open3d"
fi
export QT_QPA_PLATFORM=offscreen  # colmap links Qt; no display here
export OMP_NUM_THREADS=$threads

mkdir -p "$out/logs"
work="$out/work"
rm -rf "$work" "$out/sparse"
mkdir -p "$work/model_in" "$work/model_tri" "$out/sparse"
log="$out/pipeline.log"
: >"$log"
echo "# $prog $(date -u +%FT%TZ) threads=$threads max_image_size=$max_image_size" \
  "matcher=$matcher mesher=$mesher depth=$depth subdivide=$subdivide" \
  "two_view_tracks=$two_view_tracks" >>"$log"
total_start=$(date +%s.%N) total_cpu=0

# step NAME COMMAND...: runs COMMAND with its output in logs/NAME.log; pipeline.log gets its wall
# time and, when GNU time (/usr/bin/time, Debian package time) is present, its CPU time (user +
# system, all threads: a measure that other processes on the machine hardly change).
step() {
  local name=$1; shift
  local start end cpu=""
  local timer=()
  [ -x /usr/bin/time ] && timer=(/usr/bin/time -f "%U %S" -o "$out/logs/$name.time")
  start=$(date +%s.%N)
  if ! "${timer[@]}" "$@" >"$out/logs/$name.log" 2>&1; then
    rm -f "$out/logs/$name.time"
    tail -n 5 "$out/logs/$name.log" | sed "s/^/  /" >&2
    if [ "$name" = triangulate ] && ! grep -q "Triangulated [1-9]" "$out/logs/$name.log"; then
      die "step 'triangulate' failed: no point could be triangulated (the training photos" \
        "share too few verified matches; full output: $out/logs/$name.log)"
    fi
    die "step '$name' failed (full output: $out/logs/$name.log)"
  fi
  end=$(date +%s.%N)
  if [ -s "$out/logs/$name.time" ]; then
    cpu=$(awk 'END { printf "%.2f", $1 + $2 }' "$out/logs/$name.time")
    rm -f "$out/logs/$name.time"
    total_cpu=$(awk "BEGIN{print $total_cpu + $cpu}")
    cpu=$(printf '  cpu %8.1f s' "$cpu")
  fi
  printf '%-12s %8.1f s%s\n' "$name" "$(awk "BEGIN{print $end - $start}")" "$cpu" |
    tee -a "$log" >&2
}

step list "$python" "$here/known_poses.py" list "$sparse" "$images" "$work/images.txt"
sed 's/^/  /' "$out/logs/list.log" >&2
n_images=$(wc -l <"$work/images.txt")

step features colmap feature_extractor \
  --database_path "$work/database.db" --image_path "$images" \
  --image_list_path "$work/images.txt" \
  --SiftExtraction.use_gpu 0 --SiftExtraction.num_threads "$threads" \
  --SiftExtraction.max_image_size "$([ "$max_image_size" -gt 0 ] && echo "$max_image_size" || echo 100000)" \
  --SiftExtraction.max_num_features "$max_features"

if [ "$matcher" = auto ]; then
  matcher=$([ "$n_images" -le 40 ] && echo exhaustive || echo poses)
fi
if [ "$matcher" = poses ]; then
  step prepare "$python" "$here/known_poses.py" prepare "$sparse" "$work/database.db" \
    "$work/model_in" --pairs "$work/pairs.txt" --neighbors "$neighbors"
  step matching colmap matches_importer --database_path "$work/database.db" \
    --match_list_path "$work/pairs.txt" --match_type pairs \
    --SiftMatching.use_gpu 0 --SiftMatching.num_threads "$threads"
else
  step prepare "$python" "$here/known_poses.py" prepare "$sparse" "$work/database.db" \
    "$work/model_in"
  step matching colmap exhaustive_matcher --database_path "$work/database.db" \
    --SiftMatching.use_gpu 0 --SiftMatching.num_threads "$threads"
fi

# Poses and intrinsics are known: refine none of them (only the points are adjusted). Points seen
# by only two photos are kept unless --two-view-tracks 0 (COLMAP drops them by default, which
# suits unknown poses; with known poses they are sound, and from two photos all there is).
step triangulate colmap point_triangulator --database_path "$work/database.db" \
  --image_path "$images" --input_path "$work/model_in" --output_path "$work/model_tri" \
  --Mapper.ba_refine_focal_length 0 --Mapper.ba_refine_principal_point 0 \
  --Mapper.ba_refine_extra_params 0 --Mapper.tri_ignore_two_view_tracks "$((1 - two_view_tracks))" \
  --Mapper.num_threads "$threads"
step convert colmap model_converter --input_path "$work/model_tri" --output_path "$out/sparse" \
  --output_type TXT
step points "$python" "$here/known_poses.py" export "$out/sparse" "$out/points.ply"
grep -h . "$out/logs/points.log" | sed 's/^/  /' >&2

case "$mesher" in
  open3d)
    step mesh "$python" "$here/poisson_mesh.py" "$out/points.ply" "$out/mesh.ply" \
      --depth "$depth" --trim-quantile "${trim:-0.1}" --subdivide "$subdivide" \
      --model "$out/sparse" --target-pixels "$target_pixels" --threads "$threads"
    ;;
  colmap)
    if [ "$depth" = auto ]; then
      depth=$("$python" "$here/poisson_mesh.py" "$out/points.ply" "$work/unused.ply" --only-depth \
        2>/dev/null) || die "poisson_mesh.py --only-depth failed on $out/points.ply"
    fi
    step poisson colmap poisson_mesher --input_path "$out/points.ply" \
      --output_path "$work/poisson.ply" --PoissonMeshing.depth "$depth" \
      --PoissonMeshing.trim "${trim:-$((depth - 3))}" --PoissonMeshing.num_threads "$threads"
    step mesh "$python" "$here/poisson_mesh.py" "$out/points.ply" "$out/mesh.ply" \
      --from-mesh "$work/poisson.ply" --subdivide "$subdivide" --model "$out/sparse" \
      --target-pixels "$target_pixels" --threads "$threads"
    ;;
esac
[ "$mesher" = none ] || grep -h . "$out/logs/mesh.log" | sed 's/^/  /' >&2

[ "$keep_work" = 1 ] || rm -rf "$work"
printf '%-12s %8.1f s  cpu %8.1f s (%s images; load average %s)\n' total \
  "$(awk "BEGIN{print $(date +%s.%N) - $total_start}")" "$total_cpu" "$n_images" \
  "$(cut -d' ' -f1-3 /proc/loadavg)" | tee -a "$log" >&2
