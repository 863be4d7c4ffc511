// Process-wide settings and accounting for rephoto's programs: memory allocation and CPU time.
#pragma once

#include <spawn.h>
#include <sys/resource.h>

#include <string>
#include <string_view>

namespace rephoto {

// rephoto allocates and frees large buffers over and over: images of every view, photo decode
// buffers, per-vertex lists for every fold. glibc hands blocks above its mmap threshold back to
// the kernel when they are freed, and trims the top of the heap, so the next buffer of the same
// size is page-faulted and zeroed by the kernel again; on fountain-P11 meshes that was a
// quarter of the CPU time of colouring a mesh (bench: BM_ColorizeFile, 1.25 s -> 0.89 s).
// KeepFreedMemory serves blocks up to 32 MB (glibc's largest mmap threshold) from the heap and
// lets the heap keep up to 2 GB of freed memory for reuse: the process keeps close to its peak
// memory until it exits. Call once, early (the rephoto CLI does). No effect without glibc.
void KeepFreedMemory();

// `value` as one POSIX shell word: 'value' with each ' written as '\'' (so paths with spaces,
// quotes or $ reach a command as one literal word). The one quoting rule of the project: command
// templates (eval/command_template.h) and Slurm batch scripts (cluster/slurm_text.h) use it.
std::string ShellQuote(std::string_view value);

// User + system CPU seconds in a resource usage record (getrusage, wait4).
double CpuSeconds(const struct rusage& usage);
// User + system CPU seconds used so far by this process (all threads; not its children).
double ProcessCpuSeconds();

// posix_spawn attributes for a child rephoto starts (a reconstruction command, a Slurm client
// program): its own process group (so it and its children can be signalled together, and a
// Ctrl-C at the terminal reaches rephoto first), default handling of SIGINT, SIGTERM and SIGPIPE
// and no blocked signals (rephoto's own handlers and mask are not inherited).
// Thread safety: one object per spawn; not copyable.
class ChildSpawnAttributes {
 public:
  ChildSpawnAttributes();
  ~ChildSpawnAttributes();
  ChildSpawnAttributes(const ChildSpawnAttributes&) = delete;
  ChildSpawnAttributes& operator=(const ChildSpawnAttributes&) = delete;
  const posix_spawnattr_t* get() const { return &attributes_; }

 private:
  posix_spawnattr_t attributes_;
};

}  // namespace rephoto
