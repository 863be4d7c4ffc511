#!/usr/bin/env bash
# The paper's representation comparison (Section 5.1, Table I) on your own scene: one geometry,
# rendered as each representation rephoto has, every one evaluated with the same folds, then
# ranked in one comparison report.
#
#   vertex_colour  MESH coloured from each fold's training photos (evaluate --colorize)
#   vdt            MESH as the proxy of view-dependent texturing from each fold's training photos
#   ibr            image-based rendering: each fold's training photos warped by per-view depth
#                  maps (--depth-maps DIR, else plane-sweep stereo over the training photos;
#                  the plane sweep takes about 20x the time of vdt per fold: pass --depth-maps
#                  from your MVS, or lower --train-short-side, to trade its quality for time)
#   point_cloud    --points PLY rendered as splats (skipped without --points)
#   textured       --textured MESH (a textured OBJ/PLY) as given; without it, MESH textured
#                  from each fold's training photos only (`evaluate --texture`, texture/), like
#                  vertex_colour's --colorize
#
# vertex_colour, vdt, ibr and the built-in textured row never see a fold's test photos.
# --points and --textured are taken as given: if they were made from all photos (a global
# method) their rows are not cross-validated (paper Section 4.4), which table1.csv's note
# column says.
#
# Usage: table1.sh --scene S --mesh MESH --out DIR [options]
#   --scene S             scene (any format rephoto reads)
#   --image-root DIR      folder the scene's image names are relative to
#   --mesh MESH           geometry for vertex_colour and vdt (colours, if any, are replaced)
#   --points PLY          point cloud model (optional)
#   --textured MESH       textured mesh model (default: MESH textured per fold by rephoto texture)
#   --depth-maps DIR      ibr depth maps (default: plane sweep per fold)
#   --photo-masks DIR     masks of the photos by stem (default: the scene's)
#   --scheme S            split (default loo)
#   --eval-short-side N   render and compare at this shorter side (default 540)
#   --train-short-side N  training photos for colorize/vdt/ibr at this shorter side (default 0 =
#                         original; plane sweep cost grows with it)
#   --metrics LIST        (default 1-ncc,cb+cr,dssim)
#   --out DIR             DIR/<representation>/ run directories, DIR/table1.csv, DIR/report.html
# Environment: REPHOTO = the rephoto binary (default: build/apps/rephoto/rephoto next to this
# repository, else rephoto on PATH).
# Rerunning resumes: finished folds are reused by every evaluation.
set -euo pipefail

prog=$(basename "$0")
die() { echo "$prog: error: $*" >&2; exit 1; }
usage() { sed -n '/^# Usage:/,/^set -euo/p' "$0" | sed '$d; s/^# \{0,1\}//' >&2; exit 1; }

here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
rephoto=${REPHOTO:-}
if [ -z "$rephoto" ]; then
  if [ -x "$here/../../build/apps/rephoto/rephoto" ]; then
    rephoto="$here/../../build/apps/rephoto/rephoto"
  else
    rephoto=$(command -v rephoto) || die "no rephoto binary: build it or set REPHOTO"
  fi
fi

scene="" image_root="" mesh="" points="" textured="" depth_maps="" masks="" scheme=loo
eval_side=540 train_side=0 metrics="1-ncc,cb+cr,dssim" out=""
while [ $# -gt 0 ]; do
  case "$1" in
    --scene) scene=${2:?}; shift 2 ;;
    --image-root) image_root=${2:?}; shift 2 ;;
    --mesh) mesh=${2:?}; shift 2 ;;
    --points) points=${2:?}; shift 2 ;;
    --textured) textured=${2:?}; shift 2 ;;
    --depth-maps) depth_maps=${2:?}; shift 2 ;;
    --photo-masks) masks=${2:?}; shift 2 ;;
    --scheme) scheme=${2:?}; shift 2 ;;
    --eval-short-side) eval_side=${2:?}; shift 2 ;;
    --train-short-side) train_side=${2:?}; shift 2 ;;
    --metrics) metrics=${2:?}; shift 2 ;;
    --out) out=${2:?}; shift 2 ;;
    -h|--help) usage ;;
    *) die "unknown argument $1 (see --help)" ;;
  esac
done
[ -n "$scene" ] && [ -n "$mesh" ] && [ -n "$out" ] || usage
[ -e "$scene" ] || die "$scene: no such scene"
[ -f "$mesh" ] || die "$mesh: no such mesh"
[ -z "$points" ] || [ -f "$points" ] || die "$points: no such point cloud"
[ -z "$textured" ] || [ -f "$textured" ] || die "$textured: no such textured mesh"

common=(--scene "$scene" --scheme "$scheme" --eval-short-side "$eval_side"
        --train-short-side "$train_side" --metrics "$metrics")
[ -z "$image_root" ] || common+=(--image-root "$image_root")
[ -z "$masks" ] || common+=(--photo-masks "$masks")
mkdir -p "$out"

runs=() labels=()
evaluate() {  # NAME ARGS...
  local name=$1; shift
  echo "$prog: evaluating $name" >&2
  local rc=0
  "$rephoto" evaluate "${common[@]}" "$@" --out "$out/$name" || rc=$?
  # 0 = complete; 3 = some folds or photos failed (their rows say why): still ranked.
  [ "$rc" -eq 0 ] || [ "$rc" -eq 3 ] || die "evaluation of $name failed (exit $rc)"
  runs+=("$out/$name") labels+=("$name")
}

evaluate vertex_colour --model "$mesh" --colorize
evaluate vdt --model "$mesh" --representation vdt
if [ -n "$depth_maps" ]; then
  evaluate ibr --representation ibr --depth-maps "$depth_maps"
else
  evaluate ibr --representation ibr
fi
[ -z "$points" ] || evaluate point_cloud --model "$points"
if [ -n "$textured" ]; then
  evaluate textured --model "$textured"
else
  evaluate textured --model "$mesh" --texture
fi

"$rephoto" report "${runs[@]}" --labels "$(IFS=,; echo "${labels[*]}")" \
  --title "Representations of $(basename "$(cd "$(dirname "$mesh")" && pwd)")/$(basename "$mesh") (Table I)" \
  --csv "$out/table1.csv" --out "$out/report.html"
# table1.csv: rank, representation, medians of every metric and of completeness, and a note for
# rows that do not compare by accuracy alone (completeness more than 0.05 below the most complete
# row's, or not cross-validated).
column -s, -t "$out/table1.csv" 2>/dev/null || cat "$out/table1.csv"
echo "$prog: $out/report.html" >&2
