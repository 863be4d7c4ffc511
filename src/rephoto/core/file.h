// File helpers: atomic writes and whole-file reads.
//
// Every output rephoto writes goes through WriteFileAtomically: the content is written to
// "<path>.tmp-<pid>" in the same folder and renamed over <path> only when complete, so an
// interrupted run never leaves a half-written file under the final name.
//
// Thread safety: reentrant, but concurrent writes must go to different paths: the temporary name is
// per process (<path>.tmp-<pid>), so two threads writing one path would share it.
#pragma once

#include <filesystem>
#include <functional>
#include <string>
#include <string_view>

namespace rephoto {

// Calls write(temporary_path) and renames the temporary file to `path` afterwards. Creates
// missing parent folders. If write throws, the temporary file is removed and the exception
// propagates. Throws Error when the folder cannot be created or the rename fails.
void WriteFileAtomically(const std::filesystem::path& path,
                         const std::function<void(const std::filesystem::path&)>& write);

// Writes `content` to `path` atomically (see above).
void WriteTextFileAtomically(const std::filesystem::path& path, std::string_view content);

// Makes `to` a hard link to `from` (a copy when they are on different file systems or links
// are refused), atomically as above: `to` is replaced only when complete. Throws Error naming
// both files when neither works.
void LinkOrCopyFileAtomically(const std::filesystem::path& from, const std::filesystem::path& to);

// Reads the whole file; throws Error naming the file when it cannot be opened or read.
std::string ReadFileToString(const std::filesystem::path& path);

}  // namespace rephoto
