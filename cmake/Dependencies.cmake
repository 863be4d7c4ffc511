# Every third-party dependency is a Debian 12 package installed by scripts/install-deps.sh.
find_package(Threads REQUIRED)
find_package(TBB REQUIRED)
find_package(Eigen3 3.4 REQUIRED NO_MODULE)
find_package(nlohmann_json REQUIRED)
find_package(CLI11 REQUIRED)
find_package(fmt REQUIRED)
find_package(PkgConfig REQUIRED)
pkg_check_modules(TURBOJPEG REQUIRED IMPORTED_TARGET libturbojpeg)
pkg_check_modules(SPNG REQUIRED IMPORTED_TARGET spng)
# PNG compression (io::EncodePng): libdeflate is faster than zlib at the same size.
pkg_check_modules(DEFLATE REQUIRED IMPORTED_TARGET libdeflate)
find_package(ZLIB REQUIRED)  # tests: an independent PNG decoder
find_package(tinyexr REQUIRED)
# rephoto evaluate: config files (TOML) and input hashes (XXH3).
find_package(tomlplusplus REQUIRED)
# LPIPS convolutions (src/rephoto/lpips): oneDNN 2.6 (libdnnl-dev), threaded with OpenMP.
# Debian's dnnl-config.cmake insists on OpenCL headers (its GPU runtime) although the CPU
# engine needs none of them: the library and header are found directly instead.
find_library(REPHOTO_DNNL_LIBRARY NAMES dnnl REQUIRED)
find_path(REPHOTO_DNNL_INCLUDE oneapi/dnnl/dnnl.hpp REQUIRED)
add_library(rephoto_dnnl INTERFACE)
target_link_libraries(rephoto_dnnl INTERFACE ${REPHOTO_DNNL_LIBRARY})
target_include_directories(rephoto_dnnl SYSTEM INTERFACE ${REPHOTO_DNNL_INCLUDE})
find_package(OpenMP REQUIRED COMPONENTS CXX)
pkg_check_modules(XXHASH REQUIRED IMPORTED_TARGET libxxhash)
find_package(embree 3 QUIET)
find_package(meshoptimizer QUIET)
find_package(tinyobjloader QUIET)
if(REPHOTO_BUILD_TESTS)
  find_package(GTest REQUIRED)
endif()
if(REPHOTO_BUILD_BENCHMARKS)
  find_package(benchmark REQUIRED)
  # Only for the OpenGL comparison in bench/bench_render.cc (skipped when absent).
  find_package(OpenGL QUIET COMPONENTS OpenGL EGL)
endif()
