#include "rephoto/core/memory.h"

#include <climits>

#if defined(__GLIBC__)
#include <malloc.h>
#endif

namespace rephoto {

void KeepFreedMemory() {
#if defined(__GLIBC__)
  mallopt(M_MMAP_THRESHOLD, 32 * 1024 * 1024);  // glibc's maximum (64-bit)
  mallopt(M_TRIM_THRESHOLD, INT_MAX);
#endif
}

}  // namespace rephoto
