// tinyobjloader's implementation, compiled into fuzz_obj with the fuzzer's instrumentation
// (the library target links the prebuilt Debian library instead).
#define TINYOBJLOADER_IMPLEMENTATION
#include <tiny_obj_loader.h>
