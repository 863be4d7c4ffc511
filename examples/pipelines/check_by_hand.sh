#!/usr/bin/env bash
# What `rephoto evaluate` does, by hand with the existing CLI, for one pipeline over the folds of
# a `rephoto split` (used to verify the pipelines here and to produce the figures in README.md).
#
# Usage: check_by_hand.sh [--keep-every N] [--model mesh.ply|points.ply] [--threads T]
#                         SPLIT_DIR EVAL_SHORT_SIDE OUT_DIR PIPELINE [PIPELINE_OPTIONS...]
# For every SPLIT_DIR/fold_XX:
#   1. training set = fold_XX/train/sparse (with --keep-every N: only every N-th training image,
#      by name, starting with the first: the paper's halving of |T|);
#   2. PIPELINE [PIPELINE_OPTIONS] SPARSE IMAGE_ROOT OUT_DIR/fold_XX/recon THREADS
#      (IMAGE_ROOT = split.json's image_root: it also holds the test photos);
#   3. a mesh is coloured from the training photos only (rephoto colorize); a point cloud is
#      rendered with its own colours;
#   4. the test cameras are rendered at EVAL_SHORT_SIDE pixels (shorter side) and compared with
#      the test photos area-averaged to that size (scale_scene.py; 1-NCC and Cb+Cr, 9x9 windows).
# Prints one line per fold (median over its test images; "failed" when the pipeline failed) and
# the median over all test images of the other folds; writes OUT_DIR/summary.tsv. The rephoto binary: $REPHOTO, else `rephoto` on PATH.
set -euo pipefail

here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
die() { echo "check_by_hand.sh: error: $*" >&2; exit 1; }
keep_every=1 model=mesh.ply threads=$(nproc)
while [ $# -gt 0 ]; do
  case "$1" in
    --keep-every) keep_every=${2:?}; shift 2 ;;
    --model) model=${2:?}; shift 2 ;;
    --threads) threads=${2:?}; shift 2 ;;
    *) break ;;
  esac
done
[ $# -ge 4 ] || { sed -n '/^# Usage:/,/^# writes/p' "$0" | sed 's/^# \{0,1\}//' >&2; exit 1; }
split=$1 short=$2 out=$3
shift 3
rephoto=${REPHOTO:-rephoto}
command -v "$rephoto" >/dev/null || die "rephoto binary '$rephoto' not found (set REPHOTO)"
[ -f "$split/split.json" ] || die "$split: no split.json (run rephoto split first)"
python=/usr/bin/python3
image_root=$("$python" -c 'import json,sys; print(json.load(open(sys.argv[1]))["image_root"])' \
  "$split/split.json")
mkdir -p "$out"
printf 'fold\ttrain_images\tpipeline_s\tcolorize_s\ttest_images\tcompleteness\t1-ncc\tcb+cr\n' \
  >"$out/summary.tsv"

for fold in "$split"/fold_*; do
  name=$(basename "$fold")
  dir="$out/$name"
  rm -rf "$dir"
  mkdir -p "$dir"
  # 1. The training set (optionally thinned), as the pipeline gets it.
  "$python" - "$fold/train/sparse" "$dir/train" "$keep_every" <<'EOF'
import os, shutil, sys
src, dst, every = sys.argv[1], sys.argv[2], int(sys.argv[3])
os.makedirs(dst)
shutil.copy(os.path.join(src, "cameras.txt"), dst)
lines = open(os.path.join(src, "images.txt"), encoding="utf-8").read().split("\n")
entries, i = [], 0
while i < len(lines):
    line = lines[i].strip(); i += 1
    if not line or line.startswith("#"):
        continue
    i += 1
    entries.append((line.split(None, 9)[9], line))
entries.sort()
kept = entries[::every]
with open(os.path.join(dst, "images.txt"), "w", encoding="utf-8") as f:
    f.write("# IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n")
    for _, line in kept:
        f.write(line + "\n\n")
open(os.path.join(dst, "points3D.txt"), "w").write("# no points\n")
with open(os.path.join(dst, "..", "train.txt"), "w", encoding="utf-8") as f:
    f.writelines(name + "\n" for name, _ in kept)
EOF
  n_train=$(wc -l <"$dir/train.txt")
  # 2. The pipeline.
  start=$(date +%s.%N)
  if ! "$@" "$dir/train" "$image_root" "$dir/recon" "$threads" >"$dir/pipeline.out" 2>&1; then
    # A failed fold is reported (no reconstruction: nothing to compare) and the others go on.
    echo "check_by_hand.sh: $name: pipeline failed: $(grep -h 'error:' "$dir/pipeline.out" |
      tail -n 1)" >&2
    printf '%s\t%s\tfailed\n' "$name" "$n_train" | tee -a "$out/summary.tsv"
    continue
  fi
  pipeline_s=$(awk "BEGIN{printf \"%.1f\", $(date +%s.%N) - $start}")
  # 3. Colours from the training photos only.
  start=$(date +%s.%N)
  rendered="$dir/recon/$model"
  [ -f "$rendered" ] || die "$name: the pipeline wrote no $model"
  if grep -a -m1 -q '^element face [1-9]' "$rendered"; then
    "$rephoto" -q -j "$threads" colorize "$rendered" --scene "$dir/train" \
      --image-root "$image_root" --out "$dir/colored.ply" 2>"$dir/colorize.err"
    rendered="$dir/colored.ply"
  fi
  colorize_s=$(awk "BEGIN{printf \"%.1f\", $(date +%s.%N) - $start}")
  # 4. Rephotos of the test cameras at the evaluation size, compared with the test photos.
  "$python" "$here/scale_scene.py" "$fold/test/sparse" "$image_root" "$short" "$dir/eval"
  "$rephoto" -q -j "$threads" render "$rendered" --scene "$dir/eval/sparse" \
    --images "$dir/eval/present.txt" --out "$dir/renders"
  rm -f "$dir"/renders/*.depth.exr
  status=0
  "$rephoto" -q -j "$threads" compare --photos "$dir/eval/images" --renders "$dir/renders" \
    --metrics 1-ncc,cb+cr --no-error-images --out "$dir/compare" >/dev/null || status=$?
  [ "$status" -eq 0 ] || [ "$status" -eq 3 ] || die "$name: rephoto compare failed ($status)"
  "$python" - "$dir/compare/per_image.csv" "$name" "$n_train" "$pipeline_s" "$colorize_s" \
    >>"$out/summary.tsv" <<'EOF'
import csv, statistics, sys
rows = [r for r in csv.DictReader(open(sys.argv[1])) if r["status"] == "ok"]
med = lambda k: statistics.median(float(r[k]) for r in rows)
print("\t".join(sys.argv[2:6] + [str(len(rows))]
                + [f"{med(k):.4f}" for k in ("completeness", "1-ncc", "cb+cr")]))
EOF
  tail -n 1 "$out/summary.tsv"
done

# Median over all test images of the folds that did not fail.
"$python" - "$out" <<'EOF' | tee -a "$out/summary.tsv"
import csv, glob, os, statistics, sys
rows = []
for path in sorted(glob.glob(os.path.join(sys.argv[1], "fold_*", "compare", "per_image.csv"))):
    rows += [r for r in csv.DictReader(open(path)) if r["status"] == "ok"]
med = lambda k: statistics.median(float(r[k]) for r in rows)
if rows:
    print(f"all\t\t\t\t{len(rows)}\t"
          + "\t".join(f"{med(k):.4f}" for k in ("completeness", "1-ncc", "cb+cr")))
else:
    print("all\t\t\t\t0\tno fold has a reconstruction")
EOF
