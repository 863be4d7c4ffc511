// Process-wide resource limits for reading files that came from somewhere else.
//
// A corrupt or hostile file can claim any size in its header (a PNG of 32768x32768 pixels in
// 3 MB, a PLY of 4e9 vertices). Readers check the size such a claim would need against these
// limits BEFORE allocating, and throw rephoto::Error naming the file, what it claims and the
// command-line option that raises the limit, instead of running into an allocation failure
// ("out of memory" naming no file) or the kernel's OOM killer.
//
// Two limits:
//   MaxPixels()       pixels of one image (any reader of images, masks, depth maps).
//                     Default 2^28 = 268,435,456 = 16384 x 16384: four times the largest
//                     photogrammetry sensors (150 MP medium format, 100 MP aerial cameras),
//                     while one such image as float RGBA is 4 GiB, about what a workstation
//                     can hold a few of. Gigapixel panoramas need --max-pixels.
//   MaxMemoryBytes()  bytes one input may need once read (a model's vertex and face arrays,
//                     an image's float values). Default: half the physical memory
//                     (sysconf(_SC_PHYS_PAGES) * page size), at least 2 GiB; 16 GiB where the
//                     size of the memory cannot be found. Half, because an evaluation holds
//                     the model, photos, renderings and their error images at once; an input
//                     needing more than that cannot be evaluated on this machine anyway, and
//                     tying it to the machine lets big workstations take big models without
//                     flags.
// Both are raised (or lowered) with the CLI's global options --max-pixels N and
// --max-memory SIZE (apps/rephoto/main.cc).
//
// Thread safety: the limits are set once at start-up (by the CLI, before any work; by tests and
// fuzzers at their start) and only read afterwards. They are atomics, so a read during a set is
// not a data race, but a reader running concurrently with a set may see either value.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>

namespace rephoto {

// Default of MaxPixels(): 2^28 pixels (16384 x 16384).
inline constexpr uint64_t kDefaultMaxPixels = uint64_t{1} << 28;

// Default of MaxMemoryBytes() on this machine (see above).
uint64_t DefaultMaxMemoryBytes();

// The current limits (the defaults until set). Values are >= 1.
uint64_t MaxPixels();
uint64_t MaxMemoryBytes();

// Set the limits; 0 is an Error (a limit of zero would reject every file).
void SetMaxPixels(uint64_t pixels);
void SetMaxMemoryBytes(uint64_t bytes);

// Throws Error "<file>: <what> needs <bytes>, more than --max-memory <limit> (raise it with
// --max-memory)" when bytes > MaxMemoryBytes(). `what` describes the claim, e.g.
// "4000000000 vertices". Compute `bytes` with SaturatingMultiply so that an overflow counts as
// too much, never as a small number.
void CheckAllocation(std::string_view file, std::string_view what, uint64_t bytes);

// Checks an image of width x height pixels with `channels` values of `bytes_per_value` bytes
// each before it is allocated: throws Error naming `file` and `format` ("PNG", "depth map")
// when a side is not positive, when width * height > MaxPixels() ("<file>: PNG image of
// 32768x32768 pixels (1.07e+09) exceeds --max-pixels 268435456 (raise it with --max-pixels)")
// or when its values need more than MaxMemoryBytes() (CheckAllocation; skipped when channels
// is 0, for header-only reads that do not know the channels yet).
void CheckImageSize(std::string_view file, std::string_view format, int64_t width, int64_t height,
                    int channels, int bytes_per_value);

// a * b, or UINT64_MAX when the product does not fit in 64 bits.
uint64_t SaturatingMultiply(uint64_t a, uint64_t b);

// A size in bytes for humans: "512 B", "1.5 KiB", "48.0 GiB" (binary units).
std::string FormatBytes(uint64_t bytes);

// Parses a size as --max-memory takes it: a positive whole number of bytes, optionally followed
// by a binary unit K, M, G or T (any case, optionally followed by "B" or "iB": "16G", "512MiB",
// "1048576"). Throws Error "<option>: ..." for anything else, zero, or a size above 2^63.
uint64_t ParseByteSize(std::string_view text, std::string_view option = "--max-memory");

}  // namespace rephoto
