#include "rephoto/splat/scalar_ply.h"

#include <cstring>
#include <optional>
#include <sstream>

#include "rephoto/core/error.h"
#include "rephoto/core/file.h"
#include "rephoto/io/ply_header.h"
#include "rephoto/io/ply_types.h"

namespace rephoto::splat {
namespace {

namespace fs = std::filesystem;

std::vector<std::string> Words(const std::string& line) {
  std::istringstream in(line);
  std::vector<std::string> words;
  for (std::string word; in >> word;) words.push_back(word);
  return words;
}

}  // namespace

std::string WithVertexFloatProperty(std::string_view ply, std::string_view name,
                                    const std::vector<float>& values, std::string_view context) {
  // The header by the project's one parser (io/ply_header.h); its lines are copied as they are.
  const io::PlyHeader header = io::ParsePlyHeader(ply, context);
  const size_t body = static_cast<size_t>(header.bytes);
  REPHOTO_CHECK(header.elements.size() == 1 && header.elements[0].name == "vertex",
                "{}: PLY has elements besides 'vertex'", context);
  const io::PlyElement& vertex = header.elements[0];
  REPHOTO_CHECK(!vertex.HasList(), "{}: PLY vertex element has a list property", context);
  std::optional<size_t> existing;  // byte offset of a float property `name` in a record
  size_t record = 0;
  for (const io::PlyProperty& p : vertex.properties) {
    if (p.name == name) {
      REPHOTO_CHECK(p.type == io::PlyType::kFloat32,
                    "{}: PLY has a property '{}' that is not float", context, name);
      existing = record;
    }
    record += static_cast<size_t>(io::PlyTypeSize(p.type));
  }
  const uint64_t count = vertex.count;
  const bool little_endian = header.encoding == io::PlyEncoding::kBinaryLittleEndian;
  // The header's lines (without line ends), to insert the new property after the last one.
  std::vector<std::string> lines;
  size_t last_property = 0;
  {
    std::istringstream text{std::string(ply.substr(0, body))};
    for (std::string line; std::getline(text, line);) {
      if (!line.empty() && line.back() == '\r') line.pop_back();
      const std::vector<std::string> w = Words(line);
      if (!w.empty() && w[0] == "property") last_property = lines.size();
      if (!w.empty() && w[0] == "end_header") break;
      lines.push_back(line);
    }
  }
  REPHOTO_CHECK(little_endian, "{}: PLY is not binary_little_endian", context);
  REPHOTO_CHECK(count == values.size(), "{}: {} vertices but {} values", context, count,
                values.size());
  REPHOTO_CHECK(record > 0 && (ply.size() - body) / record >= count,
                "{}: PLY holds fewer bytes than its {} vertices need", context, count);
  std::string out;
  if (existing) {
    out.assign(ply.substr(0, body + count * record));
    for (size_t v = 0; v < count; ++v) {
      std::memcpy(out.data() + body + v * record + *existing, &values[v], 4);
    }
    return out;
  }
  for (size_t i = 0; i < lines.size(); ++i) {
    out += lines[i] + "\n";
    if (i == last_property) out += fmt::format("property float {}\n", name);
  }
  out += "end_header\n";
  out.reserve(out.size() + count * (record + 4));
  for (size_t v = 0; v < count; ++v) {
    out.append(ply.substr(body + v * record, record));
    out.append(reinterpret_cast<const char*>(&values[v]), 4);
  }
  return out;
}

void WriteGaussiansWithScalar(const fs::path& source, const GaussianModel& model,
                              std::string_view name, const std::vector<float>& values,
                              const fs::path& out) {
  REPHOTO_CHECK(values.size() == model.size(), "{}: {} Gaussians but {} values", out.string(),
                model.size(), values.size());
  std::string ply;
  bool copied = false;
  if (source.extension() != ".splat") {
    ply = ReadFileToString(source);
    try {
      ply = WithVertexFloatProperty(ply, name, values, source.string());
      copied = true;
    } catch (const Error&) {
      // Not the plain Inria layout (compressed, ascii, big endian): written anew below.
    }
  }
  if (!copied) {
    std::ostringstream stream;
    WriteInriaPly(stream, model);
    ply = WithVertexFloatProperty(stream.str(), name, values, out.string());
  }
  WriteTextFileAtomically(out, ply);
}

}  // namespace rephoto::splat
