// tinyexr's implementation (zlib for ZIP compression, as Debian builds it), compiled into
// fuzz_image with the fuzzer's instrumentation (the library target links the prebuilt Debian
// library instead).
#define TINYEXR_IMPLEMENTATION
#include <tinyexr.h>
