#include "rephoto/io/ply_header.h"

#include <charconv>

#include "rephoto/core/error.h"

namespace rephoto::io {
namespace {

constexpr size_t kMaxLine = 64 * 1024;
constexpr uint64_t kMaxHeader = 1024 * 1024;

std::vector<std::string_view> Tokens(std::string_view line) {
  std::vector<std::string_view> tokens;
  size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t' || line[i] == '\r')) ++i;
    const size_t begin = i;
    while (i < line.size() && line[i] != ' ' && line[i] != '\t' && line[i] != '\r') ++i;
    if (i > begin) tokens.push_back(line.substr(begin, i - begin));
  }
  return tokens;
}

bool IsInteger(PlyType type) { return type != PlyType::kFloat32 && type != PlyType::kFloat64; }

}  // namespace

int PlyElement::Find(std::string_view property) const {
  for (size_t i = 0; i < properties.size(); ++i) {
    if (properties[i].name == property && !properties[i].is_list) return static_cast<int>(i);
  }
  return -1;
}

bool PlyElement::HasList() const {
  for (const PlyProperty& p : properties) {
    if (p.is_list) return true;
  }
  return false;
}

uint64_t PlyElement::RecordBytes() const {
  uint64_t bytes = 0;
  for (const PlyProperty& p : properties) bytes += static_cast<uint64_t>(PlyTypeSize(p.type));
  return bytes;
}

const PlyElement* PlyHeader::Find(std::string_view element) const {
  for (const PlyElement& e : elements) {
    if (e.name == element) return &e;
  }
  return nullptr;
}

PlyHeader ParsePlyHeader(const std::function<bool(std::string& line)>& next_line,
                         std::string_view name) {
  std::string line;
  auto read = [&](PlyHeader& header) {
    if (!next_line(line)) return false;
    header.bytes += line.size() + 1;
    REPHOTO_CHECK(line.size() <= kMaxLine, "{}: header line longer than 64 KiB (not a PLY file?)",
                  name);
    REPHOTO_CHECK(header.bytes <= kMaxHeader, "{}: PLY header longer than 1 MiB", name);
    if (!line.empty() && line.back() == '\r') line.pop_back();
    return true;
  };
  PlyHeader header;
  REPHOTO_CHECK(read(header) && Tokens(line) == std::vector<std::string_view>{"ply"},
                "{}: not a PLY file (no 'ply' magic)", name);
  bool have_format = false;
  for (int number = 2;; ++number) {
    REPHOTO_CHECK(read(header), "{}: unexpected end of file in the header", name);
    const std::vector<std::string_view> t = Tokens(line);
    if (t.empty() || t[0] == "obj_info") continue;
    if (t[0] == "end_header") break;
    if (t[0] == "comment") {
      const size_t at = line.find("comment") + 7;
      const size_t text = line.find_first_not_of(" \t", at);
      header.comments.push_back(text == std::string::npos ? std::string() : line.substr(text));
      continue;
    }
    if (t[0] == "format") {
      REPHOTO_CHECK(t.size() >= 2, "{}: header line {}: format line without encoding", name,
                    number);
      if (t[1] == "ascii") {
        header.encoding = PlyEncoding::kAscii;
      } else if (t[1] == "binary_little_endian") {
        header.encoding = PlyEncoding::kBinaryLittleEndian;
      } else if (t[1] == "binary_big_endian") {
        header.encoding = PlyEncoding::kBinaryBigEndian;
      } else {
        ThrowError("{}: header line {}: unknown format '{}'", name, number, t[1]);
      }
      have_format = true;
    } else if (t[0] == "element") {
      PlyElement element;
      bool ok = t.size() == 3;
      if (ok) {
        element.name = std::string(t[1]);
        const auto [ptr, ec] =
            std::from_chars(t[2].data(), t[2].data() + t[2].size(), element.count);
        ok = ec == std::errc() && ptr == t[2].data() + t[2].size();
      }
      REPHOTO_CHECK(ok, "{}: header line {}: bad element line '{}'", name, number, line);
      header.elements.push_back(std::move(element));
    } else if (t[0] == "property") {
      REPHOTO_CHECK(!header.elements.empty(), "{}: header line {}: property before any element",
                    name, number);
      PlyProperty property;
      if (t.size() >= 2 && t[1] == "list") {
        const auto count_type = t.size() == 5 ? ParsePlyType(t[2]) : std::nullopt;
        const auto item_type = t.size() == 5 ? ParsePlyType(t[3]) : std::nullopt;
        REPHOTO_CHECK(count_type && item_type, "{}: header line {}: bad list property '{}'", name,
                      number, line);
        REPHOTO_CHECK(IsInteger(*count_type),
                      "{}: header line {}: list count type must be an integer", name, number);
        property = {std::string(t[4]), *item_type, true, *count_type};
      } else {
        const auto type = t.size() == 3 ? ParsePlyType(t[1]) : std::nullopt;
        REPHOTO_CHECK(type.has_value(), "{}: header line {}: bad property '{}'", name, number,
                      line);
        property = {std::string(t[2]), *type, false, PlyType::kUInt8};
      }
      header.elements.back().properties.push_back(std::move(property));
    } else {
      ThrowError("{}: header line {}: unknown keyword '{}'", name, number, t[0]);
    }
  }
  REPHOTO_CHECK(have_format, "{}: header has no format line", name);
  return header;
}

PlyHeader ReadPlyHeader(std::istream& in, std::string_view name) {
  return ParsePlyHeader(
      [&in](std::string& line) {
        line.clear();
        char c;
        while (in.get(c)) {
          if (c == '\n') return true;
          line.push_back(c);
          if (line.size() > kMaxLine) return true;  // refused by the parser
        }
        return !line.empty();
      },
      name);
}

PlyHeader ParsePlyHeader(std::string_view bytes, std::string_view name) {
  size_t at = 0;
  return ParsePlyHeader(
      [&](std::string& line) {
        if (at >= bytes.size()) return false;
        size_t end = bytes.find('\n', at);
        const bool complete = end != std::string_view::npos;
        if (!complete) end = bytes.size();
        line.assign(bytes.substr(at, std::min(end - at, kMaxLine + 1)));
        at = complete ? end + 1 : end;
        return complete || !line.empty();
      },
      name);
}

}  // namespace rephoto::io
