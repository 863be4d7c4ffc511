#include "rephoto/core/process.h"

#include <climits>
#include <csignal>

#if defined(__GLIBC__)
#include <malloc.h>
#endif

namespace rephoto {

std::string ShellQuote(std::string_view value) {
  std::string quoted = "'";
  for (char c : value) {
    if (c == '\'') {
      quoted += "'\\''";
    } else {
      quoted += c;
    }
  }
  quoted += '\'';
  return quoted;
}

void KeepFreedMemory() {
#if defined(__GLIBC__)
  mallopt(M_MMAP_THRESHOLD, 32 * 1024 * 1024);  // glibc's maximum (64-bit)
  mallopt(M_TRIM_THRESHOLD, INT_MAX);
#endif
}

double CpuSeconds(const struct rusage& usage) {
  return static_cast<double>(usage.ru_utime.tv_sec + usage.ru_stime.tv_sec) +
         1e-6 * static_cast<double>(usage.ru_utime.tv_usec + usage.ru_stime.tv_usec);
}

double ProcessCpuSeconds() {
  struct rusage usage {};
  return ::getrusage(RUSAGE_SELF, &usage) == 0 ? CpuSeconds(usage) : 0.0;
}

ChildSpawnAttributes::ChildSpawnAttributes() {
  posix_spawnattr_init(&attributes_);
  posix_spawnattr_setpgroup(&attributes_, 0);
  sigset_t defaults;
  sigemptyset(&defaults);
  sigaddset(&defaults, SIGINT);
  sigaddset(&defaults, SIGTERM);
  sigaddset(&defaults, SIGPIPE);
  posix_spawnattr_setsigdefault(&attributes_, &defaults);
  sigset_t no_mask;
  sigemptyset(&no_mask);
  posix_spawnattr_setsigmask(&attributes_, &no_mask);
  posix_spawnattr_setflags(&attributes_,
                           POSIX_SPAWN_SETPGROUP | POSIX_SPAWN_SETSIGDEF | POSIX_SPAWN_SETSIGMASK);
}

ChildSpawnAttributes::~ChildSpawnAttributes() { posix_spawnattr_destroy(&attributes_); }

}  // namespace rephoto
