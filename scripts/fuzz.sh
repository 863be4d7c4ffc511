#!/usr/bin/env bash
# Builds rephoto's libFuzzer targets (CMake preset "fuzz": clang, ASan + UBSan) and runs each
# for a short time over a seed corpus made from the real datasets in ../shared/data, the
# readers' test fixtures, fuzz/corpus and examples/experiments: scene readers, models (PLY,
# OBJ + MTL), images (PNG, JPEG, EXR, PFM), COLMAP depth maps, experiment files (TOML, JSON).
#
# Usage: scripts/fuzz.sh [SECONDS_PER_TARGET] [TARGET...]
#   SECONDS_PER_TARGET  default 20 (CI); use 60 or more locally
#   TARGET              e.g. fuzz_bundler (default: every fuzz_* target the build has)
# Environment: BUILD_DIR (default build-fuzz), DATA_DIR (default ../shared/data).
# Exit status: 0 when every target ran clean, 1 when one found a crash (the input is kept in
# $BUILD_DIR/fuzz-artifacts/<target>/ and the log in $BUILD_DIR/fuzz-logs/<target>.log).
set -euo pipefail
cd "$(dirname "$0")/.."
seconds="${1:-20}"
shift || true
build_dir="${BUILD_DIR:-build-fuzz}"
data_dir="${DATA_DIR:-../shared/data}"

# Configure with the fuzz preset unless the folder is already configured (scripts/test.sh
# passes the sanitize build, which holds the fuzz targets too).
if [ ! -f "$build_dir/CMakeCache.txt" ]; then cmake --preset fuzz -B "$build_dir" >/dev/null; fi
mapfile -t all_targets < <(cmake --build "$build_dir" --target help | sed -n 's/^\(fuzz_[a-z_]*\):.*/\1/p' | sort -u)
targets=("$@")
if [ ${#targets[@]} -eq 0 ]; then targets=("${all_targets[@]}"); fi
cmake --build "$build_dir" --target "${targets[@]}"

# Seed corpora from real files (copied, so the fuzzer may add its own inputs next to them).
corpus="$build_dir/fuzz-corpus"
rm -rf "$corpus"
mkdir -p "$corpus"
seed() {  # seed TARGET FILE...
  mkdir -p "$corpus/$1"
  local target="$1"
  shift
  for file in "$@"; do
    if [ -f "$file" ]; then cp "$file" "$corpus/$target/$(basename "$file")"; fi
  done
}
if [ -f "$data_dir/bundler_kermit/list.txt" ]; then
  mkdir -p "$corpus/fuzz_bundler"
  # list.txt, NUL, bundle.out (the input layout fuzz_bundler.cc expects).
  { cat "$data_dir/bundler_kermit/list.txt"; printf '\0'; cat "$data_dir/bundler_kermit/results.example/bundle.out"; } \
    > "$corpus/fuzz_bundler/kermit"
  # The first two cameras and points only: small inputs mutate faster.
  { printf 'a.jpg\nb.jpg\n\0# Bundle file v0.3\n2 2\n'
    sed -n '3,12p' "$data_dir/bundler_kermit/results.example/bundle.out"
    printf '0.1 0.2 -3\n10 20 30\n2 0 5 12.5 -3.25 1 7 -40 2\n1 1 -2\n1 2 3\n1 1 2 3.5 4.5\n'; } \
    > "$corpus/fuzz_bundler/small"
fi
seed fuzz_middlebury "$data_dir"/middlebury_temple_dino/*/*_par.txt
seed fuzz_strecha "$data_dir"/strecha_fountain_p11/gt_dense_cameras/*.camera
seed fuzz_mve fuzz/corpus/mve/*
seed fuzz_mvs_texturing_cam fuzz/corpus/mvs_texturing_cam/*
# Selector byte + file (fuzz/fuzz_splat.cc); made by fuzz/corpus/splat/make_seeds.py.
seed fuzz_splat fuzz/corpus/splat/inria_sh0 fuzz/corpus/splat/inria_sh1 \
  fuzz/corpus/splat/compressed fuzz/corpus/splat/three.splat fuzz/corpus/splat/cameras_json \
  fuzz/corpus/splat/regression_nan_tile_extent  # a finding of stop 23, kept as a seed
for colmap_file in "$data_dir"/openmvs_sceaux/colmap_text_derived/*.txt "$data_dir"/llff_fern/sparse/0/*.bin; do
  # fuzz_scene_colmap takes a selector byte before the file (see fuzz/fuzz_scene_colmap.cc);
  # the raw files still seed useful tokens.
  seed fuzz_scene_colmap "$colmap_file"
done
# Selector byte + file (fuzz/fuzz_scene_colmap.cc); made by fuzz/corpus/make_scene_seeds.py.
seed fuzz_scene_colmap fuzz/corpus/scene_colmap/*
seed fuzz_scene_transforms_json fuzz/corpus/scene_transforms_json/* \
  "$data_dir/instant_ngp_fox/transforms.json"
# Models: small hand-written meshes and point clouds (every encoding and property kind) and
# the real sparse cloud and mesh of Sceaux (the 3 MB refined mesh would slow mutation down).
seed fuzz_ply fuzz/corpus/ply/* "$data_dir/openmvs_sceaux/Sparse.ply" "$data_dir/openmvs_sceaux/scene_mesh.ply"
seed fuzz_obj fuzz/corpus/obj/*  # OBJ, NUL, MTL (see fuzz/fuzz_obj.cc)
# Images: the decoder test fixtures (every PNG variant, JPEG, EXR half/float, PFM both byte
# orders) and one real photo of each of two datasets.
seed fuzz_image src/rephoto/io/testdata/*.png src/rephoto/io/testdata/*.jpg \
  src/rephoto/io/testdata/*.exr src/rephoto/io/testdata/*.pfm \
  "$data_dir/bundler_kermit/kermit000.jpg" "$data_dir/llff_fern/images_8/image000.png"
seed fuzz_depth_map fuzz/corpus/depth_map/*
# Experiment files: fuzz_config takes a selector byte (bit 0: JSON, bit 1: sweep config).
seed fuzz_config fuzz/corpus/config/*
# The benchmark service (issue 27): request fields, and hostile archives made by
# fuzz/corpus/service_upload/make_seeds.py (those of the benchmark tests).
seed fuzz_service_request fuzz/corpus/service_request/*
seed fuzz_service_upload fuzz/corpus/service_upload/*.tar fuzz/corpus/service_upload/*.gz \
  fuzz/corpus/service_upload/*.zip
seed fuzz_torch_file src/rephoto/lpips/testdata/*.pth
for toml in examples/experiments/*.toml; do
  { printf '\000'; cat "$toml"; } > "$corpus/fuzz_config/evaluate_$(basename "$toml")"
  { printf '\002'; cat "$toml"; } > "$corpus/fuzz_config/sweep_$(basename "$toml")"
done

status=0
mkdir -p "$build_dir/fuzz-logs"
for target in "${targets[@]}"; do
  binary=$(find "$build_dir" -type f -name "$target" -perm -u+x | head -n 1)
  if [ -z "$binary" ]; then echo "fuzz.sh: $target was not built" >&2; status=1; continue; fi
  mkdir -p "$corpus/$target" "$build_dir/fuzz-artifacts/$target"
  log="$build_dir/fuzz-logs/$target.log"
  echo "fuzz.sh: $target for ${seconds}s (log: $log)"
  if ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
      "$binary" "$corpus/$target" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 \
      -artifact_prefix="$build_dir/fuzz-artifacts/$target/" -print_final_stats=1 >"$log" 2>&1; then
    grep -E "^stat::number_of_executed_units|^#[0-9]+ *DONE" "$log" | tail -n 2 | sed "s/^/  /"
  else
    echo "fuzz.sh: $target FAILED; last lines of $log:" >&2
    tail -n 30 "$log" >&2
    status=1
  fi
done
exit $status
