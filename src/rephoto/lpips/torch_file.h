// Reading the tensors of a PyTorch `torch.save` file (a state_dict of float32 tensors), without
// PyTorch and without a conversion step: the files users already have (the `lpips` package's
// weights/v0.1/alex.pth, torchvision's alexnet-owt-7be5be79.pth, ...).
//
// Two container formats, told apart by their first bytes:
//   - zip (torch >= 1.6 default): entries "<prefix>/data.pkl" (the pickle) and
//     "<prefix>/data/<key>" (one raw little-endian storage per key), all under one top folder
//     whose name is free. Only stored (uncompressed) entries, as torch writes them; zip64 sizes
//     and offsets are understood. Entries are located through the central directory and each
//     local header is checked against it.
//   - legacy (torch < 1.6, and `_use_new_zipfile_serialization=False`): a pickle of the magic
//     number 0x1950a86a20f9469cfc6c, one of the protocol version 1001, one of the system info
//     (must say little_endian), the object pickle, a pickle of the sorted storage keys, then per
//     key an int64 element count and the raw storage.
//
// The pickle is interpreted by a small virtual machine that implements only the subset
// torch.save emits for a state_dict (protocols 2 to 5): PROTO, FRAME, STOP; GLOBAL and
// STACK_GLOBAL restricted to collections.OrderedDict, torch._utils._rebuild_tensor(_v2),
// torch._utils._rebuild_parameter and torch.<Type>Storage; BINPERSID with ('storage', type, key,
// location, numel[, view]) ids; memo (BINPUT, LONG_BINPUT, MEMOIZE, BINGET, LONG_BINGET); MARK,
// tuples, lists, dicts (EMPTY_*, TUPLE*, APPEND(S), SETITEM(S)); ints (BININT, BININT1, BININT2,
// LONG1), BINFLOAT, strings and bytes; NONE, NEWTRUE, NEWFALSE; REDUCE, BUILD (its state is
// dropped: a state_dict's _metadata), POP, POP_MARK, DUP. Any other opcode or callable is an
// Error naming it: nothing in the file is ever executed or used to name a file.
//
// Every claim of the file is hostile until checked: sizes, strides and storage offsets must
// address only elements inside the storage (no overflow), storages must be as long as their ids
// say, nesting is limited to 64 levels, memo indices must exist, and the memory the tensors need
// is checked with CheckAllocation (core/limits.h) before it is allocated. Errors name the file.
//
// Thread safety: pure functions.
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <string_view>
#include <vector>

namespace rephoto::lpips {

// One tensor as a contiguous row-major float32 array (torch's strides resolved).
struct FloatTensor {
  std::vector<int64_t> shape;
  std::vector<float> values;  // product(shape) values; empty for a non-float tensor
  std::string dtype;          // the storage type: "FloatStorage", "LongStorage", ...
};

// Parameter name -> tensor, from a state_dict (a dict or OrderedDict of tensors). Entries whose
// value is not a tensor are skipped. Non-float tensors keep shape and dtype, without values.
using StateDict = std::map<std::string, FloatTensor>;

// Parses `bytes`, the whole file; `name` is used in messages. Throws Error.
StateDict ParseTorchFile(std::string_view bytes, std::string_view name);

// Reads and parses the file at `path`. Throws Error naming the file.
StateDict ReadTorchFile(const std::filesystem::path& path);

}  // namespace rephoto::lpips
