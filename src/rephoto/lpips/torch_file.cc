#include "rephoto/lpips/torch_file.h"

#include <fmt/format.h>

#include <algorithm>
#include <cstring>
#include <functional>
#include <memory>
#include <optional>
#include <unordered_map>
#include <utility>

#include "rephoto/core/error.h"
#include "rephoto/core/file.h"
#include "rephoto/core/limits.h"

namespace rephoto::lpips {
namespace {

constexpr int kMaxDepth = 64;

// ------------------------------------------------------------------------------ byte reading

class Bytes {
 public:
  Bytes(std::string_view data, std::string_view name, std::string_view what)
      : data_(data), name_(name), what_(what) {}

  size_t pos() const { return pos_; }
  size_t remaining() const { return data_.size() - pos_; }
  bool done() const { return pos_ >= data_.size(); }

  std::string_view Take(uint64_t n) {
    if (n > remaining()) {
      ThrowError("{}: {} ends early (needs {} more bytes at offset {}, {} left)", name_, what_, n,
                 pos_, remaining());
    }
    std::string_view out = data_.substr(pos_, n);
    pos_ += n;
    return out;
  }
  uint64_t Uint(int n) {  // little-endian
    const std::string_view b = Take(n);
    uint64_t v = 0;
    for (int i = n - 1; i >= 0; --i) v = (v << 8) | static_cast<uint8_t>(b[i]);
    return v;
  }
  std::string_view Line() {
    const size_t end = data_.find('\n', pos_);
    if (end == std::string_view::npos) ThrowError("{}: {} ends inside a line", name_, what_);
    std::string_view out = data_.substr(pos_, end - pos_);
    pos_ = end + 1;
    return out;
  }

 private:
  std::string_view data_;
  std::string_view name_;
  std::string_view what_;
  size_t pos_ = 0;
};

// ------------------------------------------------------------------------------- pickle values

struct Value;
using ValuePtr = std::shared_ptr<Value>;

struct StorageRef {
  std::string key;
  std::string type;  // "FloatStorage", ...
  int element_size = 4;
  uint64_t numel = 0;
};

struct TensorRef {
  std::shared_ptr<const StorageRef> storage;
  uint64_t offset = 0;
  std::vector<int64_t> size, stride;
};

struct Value {
  enum class Kind {
    kNone, kBool, kInt, kFloat, kString, kBytes, kTuple, kList, kDict, kGlobal, kStorage,
    kStorageType, kTensor, kMark
  };
  Kind kind = Kind::kNone;
  int depth = 1;
  int64_t i = 0;
  double f = 0;
  std::string s;  // string, bytes, global "module.name", storage type name
  std::vector<ValuePtr> items;                        // tuple, list
  std::vector<std::pair<ValuePtr, ValuePtr>> pairs;   // dict (insertion order)
  std::shared_ptr<const StorageRef> storage;
  std::shared_ptr<const TensorRef> tensor;
  // Set once the value is inside a container (or an argument): a list or dict may not change
  // after that, so no cycle can form (torch.save completes every child before its parent).
  bool frozen = false;
};

std::string_view KindName(Value::Kind k) {
  switch (k) {
    case Value::Kind::kNone: return "None";
    case Value::Kind::kBool: return "bool";
    case Value::Kind::kInt: return "int";
    case Value::Kind::kFloat: return "float";
    case Value::Kind::kString: return "str";
    case Value::Kind::kBytes: return "bytes";
    case Value::Kind::kTuple: return "tuple";
    case Value::Kind::kList: return "list";
    case Value::Kind::kDict: return "dict";
    case Value::Kind::kGlobal: return "global";
    case Value::Kind::kStorage: return "storage";
    case Value::Kind::kStorageType: return "storage type";
    case Value::Kind::kTensor: return "tensor";
    case Value::Kind::kMark: return "mark";
  }
  return "?";
}

int StorageElementSize(std::string_view type) {
  static const std::pair<std::string_view, int> kTypes[] = {
      {"FloatStorage", 4}, {"DoubleStorage", 8}, {"HalfStorage", 2}, {"BFloat16Storage", 2},
      {"LongStorage", 8},  {"IntStorage", 4},    {"ShortStorage", 2}, {"CharStorage", 1},
      {"ByteStorage", 1},  {"BoolStorage", 1}};
  for (const auto& [name, size] : kTypes) {
    if (name == type) return size;
  }
  return 0;
}

// The storage bytes of a key, found by the caller's container.
using StorageLookup = std::function<std::string_view(const StorageRef&)>;

class Unpickler {
 public:
  Unpickler(std::string_view data, std::string_view name, std::string_view what)
      : in_(data, name, what), name_(name), what_(what) {}

  // Runs to STOP; returns the object. Persistent ids are resolved to StorageRefs.
  ValuePtr Run() {
    for (;;) {
      const size_t at = in_.pos();
      const uint8_t op = static_cast<uint8_t>(in_.Take(1)[0]);
      if (op == '.') {  // STOP
        ValuePtr result = Pop(op);
        return result;
      }
      Step(op, at);
    }
  }
  size_t consumed() const { return in_.pos(); }

 private:
  [[noreturn]] void Fail(const std::string& message) const {
    ThrowError("{}: {}: {}", name_, what_, message);
  }

  ValuePtr Make(Value v) {
    int depth = 0;
    for (const ValuePtr& item : v.items) depth = std::max(depth, item->depth);
    for (const auto& [k, val] : v.pairs) depth = std::max({depth, k->depth, val->depth});
    v.depth = depth + 1;
    if (v.depth > kMaxDepth) Fail(fmt::format("objects nested deeper than {}", kMaxDepth));
    for (const ValuePtr& item : v.items) item->frozen = true;
    return std::make_shared<Value>(std::move(v));
  }
  // Checks and records that `item` goes into the list or dict `container` (see Value::frozen).
  void Insert(Value* container, const ValuePtr& item) {
    if (container->frozen) Fail("changes a list or dict that is already inside another object");
    if (item.get() == container) Fail("puts a list or dict into itself");
    item->frozen = true;
    container->depth = std::max(container->depth, item->depth + 1);
    if (container->depth > kMaxDepth) {
      Fail(fmt::format("objects nested deeper than {}", kMaxDepth));
    }
  }
  ValuePtr Simple(Value::Kind kind) {
    Value v;
    v.kind = kind;
    return Make(std::move(v));
  }
  void Push(ValuePtr v) {
    if (stack_.size() > (size_t{1} << 20)) Fail("stack too deep");
    stack_.push_back(std::move(v));
  }
  ValuePtr Pop(uint8_t op) {
    if (stack_.empty() || stack_.back()->kind == Value::Kind::kMark) {
      Fail(fmt::format("opcode 0x{:02x} finds an empty stack", op));
    }
    ValuePtr v = std::move(stack_.back());
    stack_.pop_back();
    return v;
  }
  ValuePtr& Top(uint8_t op) {
    if (stack_.empty() || stack_.back()->kind == Value::Kind::kMark) {
      Fail(fmt::format("opcode 0x{:02x} finds an empty stack", op));
    }
    return stack_.back();
  }
  // Items above the topmost mark (mark removed).
  std::vector<ValuePtr> PopToMark(uint8_t op) {
    size_t m = stack_.size();
    while (m > 0 && stack_[m - 1]->kind != Value::Kind::kMark) --m;
    if (m == 0) Fail(fmt::format("opcode 0x{:02x} without a MARK", op));
    std::vector<ValuePtr> items(std::make_move_iterator(stack_.begin() + m),
                                std::make_move_iterator(stack_.end()));
    stack_.resize(m - 1);
    return items;
  }
  void Memo(uint64_t index) {
    if (stack_.empty()) Fail("memo put on an empty stack");
    if (memo_.size() > (size_t{1} << 20) && !memo_.count(index)) Fail("memo too large");
    memo_[index] = stack_.back();
  }
  void Get(uint64_t index) {
    auto it = memo_.find(index);
    if (it == memo_.end()) Fail(fmt::format("memo entry {} does not exist", index));
    Push(it->second);
  }
  ValuePtr Str(Value::Kind kind, std::string_view text) {
    Value v;
    v.kind = kind;
    v.s = std::string(text);
    return Make(std::move(v));
  }
  ValuePtr Int(int64_t i) {
    Value v;
    v.kind = Value::Kind::kInt;
    v.i = i;
    return Make(std::move(v));
  }
  ValuePtr Global(std::string_view module, std::string_view name) {
    const std::string full = fmt::format("{}.{}", module, name);
    if (full == "collections.OrderedDict" || full == "torch._utils._rebuild_tensor_v2" ||
        full == "torch._utils._rebuild_tensor" || full == "torch._utils._rebuild_parameter") {
      return Str(Value::Kind::kGlobal, full);
    }
    if (module == "torch" && StorageElementSize(name) > 0) {
      return Str(Value::Kind::kStorageType, name);
    }
    Fail(fmt::format("refers to '{}', which a state_dict of tensors does not use", full));
  }

  // ('storage', type, key, location, numel[, view_metadata])
  ValuePtr PersistentId(const ValuePtr& pid) {
    const std::vector<ValuePtr>& t = pid->items;
    if (pid->kind != Value::Kind::kTuple || t.size() < 5 || t.size() > 6 ||
        t[0]->kind != Value::Kind::kString || t[0]->s != "storage" ||
        t[1]->kind != Value::Kind::kStorageType || t[2]->kind != Value::Kind::kString ||
        t[4]->kind != Value::Kind::kInt || t[4]->i < 0) {
      Fail("a persistent id is not ('storage', type, key, location, size)");
    }
    if (t.size() == 6 && t[5]->kind != Value::Kind::kNone) {
      Fail("storage views (legacy view_metadata) are not supported");
    }
    auto ref = std::make_shared<StorageRef>();
    ref->type = t[1]->s;
    ref->element_size = StorageElementSize(ref->type);
    ref->key = t[2]->s;
    ref->numel = static_cast<uint64_t>(t[4]->i);
    auto it = storages_.find(ref->key);
    if (it != storages_.end()) {
      if (it->second->type != ref->type || it->second->numel != ref->numel) {
        Fail(fmt::format("storage '{}' is declared twice with different types or sizes",
                         ref->key));
      }
      ref = std::const_pointer_cast<StorageRef>(it->second);
    } else {
      if (storages_.size() > 100000) Fail("too many storages");
      storages_[ref->key] = ref;
    }
    Value v;
    v.kind = Value::Kind::kStorage;
    v.storage = ref;
    return Make(std::move(v));
  }

  std::vector<int64_t> IntTuple(const ValuePtr& v, std::string_view what) {
    if (v->kind != Value::Kind::kTuple) Fail(fmt::format("tensor {} is not a tuple", what));
    std::vector<int64_t> out;
    for (const ValuePtr& item : v->items) {
      if (item->kind != Value::Kind::kInt || item->i < 0) {
        Fail(fmt::format("tensor {} holds a non-integer or a negative value", what));
      }
      out.push_back(item->i);
    }
    return out;
  }

  ValuePtr Reduce(const ValuePtr& callable, const ValuePtr& args) {
    if (callable->kind != Value::Kind::kGlobal) {
      Fail(fmt::format("REDUCE calls a {}", KindName(callable->kind)));
    }
    if (args->kind != Value::Kind::kTuple) Fail("REDUCE arguments are not a tuple");
    const std::vector<ValuePtr>& a = args->items;
    if (callable->s == "collections.OrderedDict") {
      if (!a.empty()) Fail("OrderedDict() with arguments");
      return Simple(Value::Kind::kDict);
    }
    if (callable->s == "torch._utils._rebuild_parameter") {
      if (a.empty() || a[0]->kind != Value::Kind::kTensor) {
        Fail("_rebuild_parameter without a tensor");
      }
      return a[0];
    }
    // _rebuild_tensor(storage, offset, size, stride) and _v2(..., requires_grad, hooks[, meta]).
    const bool v2 = callable->s == "torch._utils._rebuild_tensor_v2";
    if (a.size() < 4 || (v2 && a.size() > 7) || (!v2 && a.size() != 4) ||
        a[0]->kind != Value::Kind::kStorage || a[1]->kind != Value::Kind::kInt || a[1]->i < 0) {
      Fail(fmt::format("{} with unexpected arguments", callable->s));
    }
    auto tensor = std::make_shared<TensorRef>();
    tensor->storage = a[0]->storage;
    tensor->offset = static_cast<uint64_t>(a[1]->i);
    tensor->size = IntTuple(a[2], "size");
    tensor->stride = IntTuple(a[3], "stride");
    if (tensor->size.size() != tensor->stride.size()) Fail("tensor size and stride differ in rank");
    if (tensor->size.size() > 8) Fail("tensor of more than 8 dimensions");
    // Every addressed element must lie in the storage: offset + sum((size-1)*stride) < numel.
    bool empty = false;
    uint64_t last = tensor->offset;
    for (size_t d = 0; d < tensor->size.size(); ++d) {
      if (tensor->size[d] == 0) empty = true;
      const uint64_t reach = SaturatingMultiply(
          static_cast<uint64_t>(std::max<int64_t>(tensor->size[d] - 1, 0)),
          static_cast<uint64_t>(tensor->stride[d]));
      last = reach > UINT64_MAX - last ? UINT64_MAX : last + reach;
    }
    if (!empty && last >= tensor->storage->numel) {
      Fail(fmt::format("a tensor reaches element {} of storage '{}', which has {}", last,
                       tensor->storage->key, tensor->storage->numel));
    }
    Value v;
    v.kind = Value::Kind::kTensor;
    v.tensor = tensor;
    return Make(std::move(v));
  }

  void Step(uint8_t op, size_t at) {
    switch (op) {
      case 0x80:  // PROTO
        if (const uint64_t p = in_.Uint(1); p < 2 || p > 5) {
          Fail(fmt::format("pickle protocol {} is not one torch.save writes", p));
        }
        return;
      case 0x95:  // FRAME
        in_.Uint(8);
        return;
      case 'c': {  // GLOBAL
        const std::string_view module = in_.Line();
        const std::string_view name = in_.Line();
        Push(Global(module, name));
        return;
      }
      case 0x93: {  // STACK_GLOBAL
        const ValuePtr name = Pop(op);
        const ValuePtr module = Pop(op);
        if (name->kind != Value::Kind::kString || module->kind != Value::Kind::kString) {
          Fail("STACK_GLOBAL on non-strings");
        }
        Push(Global(module->s, name->s));
        return;
      }
      case 'Q':  // BINPERSID
        Push(PersistentId(Pop(op)));
        return;
      case 'q':
        Memo(in_.Uint(1));
        return;
      case 'r':
        Memo(in_.Uint(4));
        return;
      case 0x94:  // MEMOIZE
        Memo(memo_.size());
        return;
      case 'h':
        Get(in_.Uint(1));
        return;
      case 'j':
        Get(in_.Uint(4));
        return;
      case '(':  // MARK
        Push(Simple(Value::Kind::kMark));
        return;
      case ')':  // EMPTY_TUPLE
        Push(Simple(Value::Kind::kTuple));
        return;
      case 't': {  // TUPLE
        Value v;
        v.kind = Value::Kind::kTuple;
        v.items = PopToMark(op);
        Push(Make(std::move(v)));
        return;
      }
      case 0x85:
      case 0x86:
      case 0x87: {  // TUPLE1..3
        Value v;
        v.kind = Value::Kind::kTuple;
        v.items.resize(op - 0x84);
        for (size_t k = v.items.size(); k-- > 0;) v.items[k] = Pop(op);
        Push(Make(std::move(v)));
        return;
      }
      case ']':  // EMPTY_LIST
        Push(Simple(Value::Kind::kList));
        return;
      case '}':  // EMPTY_DICT
        Push(Simple(Value::Kind::kDict));
        return;
      case 'a':
      case 'e': {  // APPEND, APPENDS
        std::vector<ValuePtr> items;
        if (op == 'a') {
          items.push_back(Pop(op));
        } else {
          items = PopToMark(op);
        }
        Value& list = *Top(op);
        if (list.kind != Value::Kind::kList) Fail("APPEND to a non-list");
        for (ValuePtr& item : items) Insert(&list, item);
        for (ValuePtr& item : items) list.items.push_back(std::move(item));
        return;
      }
      case 's':
      case 'u': {  // SETITEM, SETITEMS
        std::vector<ValuePtr> items;
        if (op == 's') {
          ValuePtr value = Pop(op);
          ValuePtr key = Pop(op);
          items = {key, value};
        } else {
          items = PopToMark(op);
        }
        if (items.size() % 2 != 0) Fail("SETITEMS with an odd number of items");
        Value& dict = *Top(op);
        if (dict.kind != Value::Kind::kDict) Fail("SETITEM on a non-dict");
        for (ValuePtr& item : items) Insert(&dict, item);
        for (size_t k = 0; k < items.size(); k += 2) dict.pairs.emplace_back(items[k], items[k + 1]);
        return;
      }
      case 'J':
        Push(Int(static_cast<int32_t>(in_.Uint(4))));
        return;
      case 'K':
        Push(Int(static_cast<int64_t>(in_.Uint(1))));
        return;
      case 'M':
        Push(Int(static_cast<int64_t>(in_.Uint(2))));
        return;
      case 0x8a: {  // LONG1: little-endian two's complement of n bytes
        const uint64_t n = in_.Uint(1);
        const std::string_view b = in_.Take(n);
        if (n > 8) {
          // Only the legacy magic number is this long: keep it as a string of its bytes.
          Push(Str(Value::Kind::kBytes, b));
          return;
        }
        uint64_t v = 0;
        for (size_t k = n; k-- > 0;) v = (v << 8) | static_cast<uint8_t>(b[k]);
        if (n > 0 && n < 8 && (static_cast<uint8_t>(b[n - 1]) & 0x80)) v |= ~uint64_t{0} << (8 * n);
        Push(Int(static_cast<int64_t>(v)));
        return;
      }
      case 'G': {  // BINFLOAT, big-endian
        const std::string_view b = in_.Take(8);
        uint64_t bits = 0;
        for (char c : b) bits = (bits << 8) | static_cast<uint8_t>(c);
        Value v;
        v.kind = Value::Kind::kFloat;
        std::memcpy(&v.f, &bits, 8);
        Push(Make(std::move(v)));
        return;
      }
      case 'X':  // BINUNICODE
        Push(Str(Value::Kind::kString, in_.Take(in_.Uint(4))));
        return;
      case 0x8c:  // SHORT_BINUNICODE
        Push(Str(Value::Kind::kString, in_.Take(in_.Uint(1))));
        return;
      case 0x8d:  // BINUNICODE8
        Push(Str(Value::Kind::kString, in_.Take(in_.Uint(8))));
        return;
      case 'T':  // BINSTRING (python 2)
        Push(Str(Value::Kind::kString, in_.Take(in_.Uint(4))));
        return;
      case 'U':  // SHORT_BINSTRING
        Push(Str(Value::Kind::kString, in_.Take(in_.Uint(1))));
        return;
      case 'B':  // BINBYTES
        Push(Str(Value::Kind::kBytes, in_.Take(in_.Uint(4))));
        return;
      case 'C':  // SHORT_BINBYTES
        Push(Str(Value::Kind::kBytes, in_.Take(in_.Uint(1))));
        return;
      case 'N':
        Push(Simple(Value::Kind::kNone));
        return;
      case 0x88:
      case 0x89: {
        Value v;
        v.kind = Value::Kind::kBool;
        v.i = op == 0x88;
        Push(Make(std::move(v)));
        return;
      }
      case 'R': {  // REDUCE
        const ValuePtr args = Pop(op);
        const ValuePtr callable = Pop(op);
        args->frozen = true;
        Push(Reduce(callable, args));
        return;
      }
      case 'b':  // BUILD: the state of an OrderedDict (state_dict._metadata) is dropped
        Pop(op)->frozen = true;
        Top(op);
        return;
      case '0':  // POP
        Pop(op);
        return;
      case '1':  // POP_MARK
        PopToMark(op);
        return;
      case '2':  // DUP
        Push(Top(op));
        return;
      default:
        Fail(fmt::format("unsupported pickle opcode 0x{:02x} at offset {}", op, at));
    }
  }

  Bytes in_;
  std::string_view name_;
  std::string_view what_;
  std::vector<ValuePtr> stack_;
  std::unordered_map<uint64_t, ValuePtr> memo_;

 public:
  std::map<std::string, std::shared_ptr<const StorageRef>> storages_;
};

// ------------------------------------------------------------------------------------- zip

struct ZipEntry {
  uint64_t data_offset = 0;
  uint64_t size = 0;
};

// Stored entries of a zip held in memory, by name.
std::map<std::string, ZipEntry> ReadZipDirectory(std::string_view zip, std::string_view name) {
  const auto u = [&](uint64_t at, int n) -> uint64_t {
    if (at > zip.size() || static_cast<uint64_t>(n) > zip.size() - at) {
      ThrowError("{}: zip structure points outside the file (offset {})", name, at);
    }
    uint64_t v = 0;
    for (int i = n - 1; i >= 0; --i) v = (v << 8) | static_cast<uint8_t>(zip[at + i]);
    return v;
  };
  // End of central directory: within the last 22 + 65535 bytes.
  if (zip.size() < 22) ThrowError("{}: too short for a zip file", name);
  size_t eocd = std::string_view::npos;
  const size_t lowest = zip.size() > 22 + 65535 ? zip.size() - 22 - 65535 : 0;
  for (size_t at = zip.size() - 22 + 1; at-- > lowest;) {
    if (u(at, 4) == 0x06054b50) {
      eocd = at;
      break;
    }
  }
  if (eocd == std::string_view::npos) ThrowError("{}: no zip end-of-directory record", name);
  uint64_t count = u(eocd + 10, 2);
  uint64_t dir_size = u(eocd + 12, 4);
  uint64_t dir_offset = u(eocd + 16, 4);
  if ((count == 0xFFFF || dir_size == 0xFFFFFFFF || dir_offset == 0xFFFFFFFF) && eocd >= 20 &&
      u(eocd - 20, 4) == 0x07064b50) {  // zip64 locator
    const uint64_t eocd64 = u(eocd - 20 + 8, 8);
    if (u(eocd64, 4) != 0x06064b50) ThrowError("{}: bad zip64 end-of-directory record", name);
    count = u(eocd64 + 32, 8);
    dir_size = u(eocd64 + 40, 8);
    dir_offset = u(eocd64 + 48, 8);
  }
  if (dir_offset > zip.size() || dir_size > zip.size() - dir_offset) {
    ThrowError("{}: zip directory outside the file", name);
  }
  if (count > dir_size / 46) ThrowError("{}: zip directory claims {} entries", name, count);
  std::map<std::string, ZipEntry> entries;
  uint64_t at = dir_offset;
  for (uint64_t k = 0; k < count; ++k) {
    if (u(at, 4) != 0x02014b50) ThrowError("{}: bad zip directory entry {}", name, k);
    const uint64_t method = u(at + 10, 2);
    uint64_t compressed = u(at + 20, 4);
    uint64_t size = u(at + 24, 4);
    const uint64_t name_length = u(at + 28, 2);
    const uint64_t extra_length = u(at + 30, 2);
    const uint64_t comment_length = u(at + 32, 2);
    uint64_t local = u(at + 42, 4);
    const uint64_t end = at + 46 + name_length + extra_length + comment_length;
    if (end > dir_offset + dir_size) ThrowError("{}: zip directory entry {} overruns", name, k);
    const std::string entry_name(zip.substr(at + 46, name_length));
    // zip64 extended information: the fields that are 0xFFFFFFFF, in this order.
    uint64_t extra = at + 46 + name_length;
    const uint64_t extra_end = extra + extra_length;
    while (extra + 4 <= extra_end) {
      const uint64_t id = u(extra, 2), length = u(extra + 2, 2);
      if (extra + 4 + length > extra_end) break;
      if (id == 0x0001) {
        uint64_t field = extra + 4;
        const auto next = [&](uint64_t* value) {
          if (*value != 0xFFFFFFFF) return;
          if (field + 8 > extra + 4 + length) {
            ThrowError("{}: short zip64 field of entry '{}'", name, entry_name);
          }
          *value = u(field, 8);
          field += 8;
        };
        next(&size);
        next(&compressed);
        next(&local);
      }
      extra += 4 + length;
    }
    at = end;
    if (method != 0 || compressed != size) {
      ThrowError("{}: zip entry '{}' is compressed (method {}); torch.save stores entries "
                 "uncompressed",
                 name, entry_name, method);
    }
    if (u(local, 4) != 0x04034b50) {
      ThrowError("{}: zip entry '{}' has no local header at offset {}", name, entry_name, local);
    }
    const uint64_t data = local + 30 + u(local + 26, 2) + u(local + 28, 2);
    if (data > zip.size() || size > zip.size() - data) {
      ThrowError("{}: zip entry '{}' ({} bytes at {}) lies outside the file", name, entry_name,
                 size, data);
    }
    if (!entries.emplace(entry_name, ZipEntry{data, size}).second) {
      ThrowError("{}: zip entry '{}' appears twice", name, entry_name);
    }
  }
  return entries;
}

// ----------------------------------------------------------------------------- tensors

float HalfToFloat(uint16_t h) {
  const uint32_t sign = (h & 0x8000u) << 16;
  uint32_t exponent = (h >> 10) & 0x1F, mantissa = h & 0x3FF;
  uint32_t bits;
  if (exponent == 0) {
    if (mantissa == 0) {
      bits = sign;
    } else {  // subnormal
      exponent = 127 - 15 + 1;
      while ((mantissa & 0x400) == 0) {
        mantissa <<= 1;
        --exponent;
      }
      bits = sign | (exponent << 23) | ((mantissa & 0x3FF) << 13);
    }
  } else if (exponent == 31) {
    bits = sign | 0x7F800000u | (mantissa << 13);
  } else {
    bits = sign | ((exponent + 127 - 15) << 23) | (mantissa << 13);
  }
  float f;
  std::memcpy(&f, &bits, 4);
  return f;
}

StateDict BuildStateDict(const ValuePtr& root, std::string_view name,
                         const std::function<std::string_view(const StorageRef&)>& storage_bytes) {
  if (root->kind != Value::Kind::kDict) {
    ThrowError("{}: holds a {}, not a state_dict (a dict of tensors)", name, KindName(root->kind));
  }
  // Memory of all float tensors, checked before any is allocated.
  uint64_t total = 0;
  for (const auto& [key, value] : root->pairs) {
    if (value->kind != Value::Kind::kTensor) continue;
    uint64_t count = 1;
    for (int64_t s : value->tensor->size) count = SaturatingMultiply(count, s);
    total = SaturatingMultiply(count, 4) > UINT64_MAX - total ? UINT64_MAX
                                                              : total + SaturatingMultiply(count, 4);
  }
  CheckAllocation(name, "the tensors of the state_dict", total);
  StateDict out;
  for (const auto& [key, value] : root->pairs) {
    if (value->kind != Value::Kind::kTensor) continue;
    if (key->kind != Value::Kind::kString) {
      ThrowError("{}: a state_dict key is a {}, not a string", name, KindName(key->kind));
    }
    const TensorRef& t = *value->tensor;
    FloatTensor tensor;
    tensor.shape = t.size;
    tensor.dtype = t.storage->type;
    uint64_t count = 1;
    for (int64_t s : t.size) count *= static_cast<uint64_t>(s);
    const bool floating = t.storage->type == "FloatStorage" || t.storage->type == "HalfStorage" ||
                          t.storage->type == "DoubleStorage";
    if (floating && count > 0) {
      const std::string_view bytes = storage_bytes(*t.storage);
      tensor.values.resize(count);
      const int rank = static_cast<int>(t.size.size());
      std::vector<int64_t> index(rank, 0);
      for (uint64_t n = 0; n < count; ++n) {
        uint64_t element = t.offset;
        for (int d = 0; d < rank; ++d) element += static_cast<uint64_t>(index[d] * t.stride[d]);
        const char* p = bytes.data() + element * t.storage->element_size;
        float v;
        if (t.storage->element_size == 4) {
          std::memcpy(&v, p, 4);
        } else if (t.storage->element_size == 8) {
          double d;
          std::memcpy(&d, p, 8);
          v = static_cast<float>(d);
        } else {
          uint16_t h;
          std::memcpy(&h, p, 2);
          v = HalfToFloat(h);
        }
        tensor.values[n] = v;
        for (int d = rank - 1; d >= 0; --d) {
          if (++index[d] < t.size[d]) break;
          index[d] = 0;
        }
      }
    }
    if (!out.emplace(key->s, std::move(tensor)).second) {
      ThrowError("{}: state_dict key '{}' appears twice", name, key->s);
    }
  }
  return out;
}

std::string_view CheckedStorage(std::string_view bytes, const StorageRef& ref,
                                std::string_view name) {
  const uint64_t need = SaturatingMultiply(ref.numel, static_cast<uint64_t>(ref.element_size));
  if (bytes.size() < need) {
    ThrowError("{}: storage '{}' holds {} bytes, its id claims {} {} elements ({} bytes)", name,
               ref.key, bytes.size(), ref.numel, ref.type, need);
  }
  return bytes;
}

StateDict ParseZip(std::string_view bytes, std::string_view name) {
  const std::map<std::string, ZipEntry> entries = ReadZipDirectory(bytes, name);
  std::string prefix;
  const ZipEntry* pickle = nullptr;
  for (const auto& [entry_name, entry] : entries) {
    const size_t slash = entry_name.find('/');
    if (slash != std::string::npos && entry_name.substr(slash) == "/data.pkl") {
      if (pickle) ThrowError("{}: more than one data.pkl", name);
      prefix = entry_name.substr(0, slash + 1);
      pickle = &entry;
    }
  }
  if (!pickle) ThrowError("{}: zip archive without <folder>/data.pkl: not a torch.save file", name);
  Unpickler unpickler(bytes.substr(pickle->data_offset, pickle->size), name, "data.pkl");
  const ValuePtr root = unpickler.Run();
  return BuildStateDict(root, name, [&](const StorageRef& ref) {
    auto it = entries.find(prefix + "data/" + ref.key);
    if (it == entries.end()) {
      ThrowError("{}: storage '{}' has no entry {}data/{}", name, ref.key, prefix, ref.key);
    }
    return CheckedStorage(bytes.substr(it->second.data_offset, it->second.size), ref, name);
  });
}

StateDict ParseLegacy(std::string_view bytes, std::string_view name) {
  size_t at = 0;
  const auto next = [&](std::string_view what) {
    Unpickler unpickler(bytes.substr(at), name, what);
    ValuePtr v = unpickler.Run();
    at += unpickler.consumed();
    return std::make_pair(v, std::move(unpickler.storages_));
  };
  const ValuePtr magic = next("magic number").first;
  static constexpr unsigned char kMagic[] = {0x6c, 0xfc, 0x9c, 0x46, 0xf9, 0x20, 0x6a, 0xa8, 0x50,
                                             0x19};
  if (magic->kind != Value::Kind::kBytes ||
      magic->s != std::string_view(reinterpret_cast<const char*>(kMagic), sizeof(kMagic))) {
    ThrowError("{}: not a torch.save file (neither a zip archive nor the legacy magic number)",
               name);
  }
  const ValuePtr protocol = next("protocol version").first;
  if (protocol->kind != Value::Kind::kInt || protocol->i != 1001) {
    ThrowError("{}: legacy torch.save protocol {} (expected 1001)", name,
               protocol->kind == Value::Kind::kInt ? protocol->i : -1);
  }
  const ValuePtr info = next("system info").first;
  if (info->kind == Value::Kind::kDict) {
    for (const auto& [key, value] : info->pairs) {
      if (key->kind == Value::Kind::kString && key->s == "little_endian" &&
          value->kind == Value::Kind::kBool && value->i == 0) {
        ThrowError("{}: written on a big-endian machine; not supported", name);
      }
    }
  }
  auto [root, storages] = next("object pickle");
  const ValuePtr keys = next("storage keys").first;
  if (keys->kind != Value::Kind::kList) ThrowError("{}: storage key list is not a list", name);
  std::map<std::string, std::string_view> data;
  for (const ValuePtr& key : keys->items) {
    if (key->kind != Value::Kind::kString) ThrowError("{}: a storage key is not a string", name);
    auto it = storages.find(key->s);
    if (it == storages.end()) ThrowError("{}: storage key '{}' is not used", name, key->s);
    Bytes in(bytes.substr(at), name, "storage data");
    const uint64_t numel = in.Uint(8);
    if (numel != it->second->numel) {
      ThrowError("{}: storage '{}' holds {} elements, its id says {}", name, key->s, numel,
                 it->second->numel);
    }
    const uint64_t size =
        SaturatingMultiply(numel, static_cast<uint64_t>(it->second->element_size));
    const std::string_view raw = in.Take(size);
    at += 8 + size;
    if (!data.emplace(key->s, raw).second) {
      ThrowError("{}: storage '{}' listed twice", name, key->s);
    }
  }
  return BuildStateDict(root, name, [&](const StorageRef& ref) {
    auto it = data.find(ref.key);
    if (it == data.end()) ThrowError("{}: storage '{}' has no data", name, ref.key);
    return CheckedStorage(it->second, ref, name);
  });
}

}  // namespace

StateDict ParseTorchFile(std::string_view bytes, std::string_view name) {
  if (bytes.size() >= 4 && bytes.substr(0, 4) == std::string_view("PK\x03\x04", 4)) {
    return ParseZip(bytes, name);
  }
  // Legacy: PROTO n, LONG1 of 10 bytes (the magic number).
  if (bytes.size() < 14 || static_cast<uint8_t>(bytes[0]) != 0x80 ||
      bytes.substr(2, 2) != std::string_view("\x8a\x0a", 2)) {
    ThrowError("{}: not a torch.save file (neither a zip archive nor the legacy format)", name);
  }
  return ParseLegacy(bytes, name);
}

StateDict ReadTorchFile(const std::filesystem::path& path) {
  std::error_code ec;
  const uintmax_t size = std::filesystem::file_size(path, ec);
  REPHOTO_CHECK(!ec, "{}: cannot read: {}", path.string(), ec.message());
  CheckAllocation(path.string(), "reading the file", size);
  const std::string bytes = ReadFileToString(path);
  return ParseTorchFile(bytes, path.string());
}

}  // namespace rephoto::lpips
