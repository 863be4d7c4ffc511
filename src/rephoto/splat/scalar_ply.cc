#include "rephoto/splat/scalar_ply.h"

#include <cstring>
#include <optional>
#include <sstream>

#include "rephoto/core/error.h"
#include "rephoto/core/file.h"
#include "rephoto/io/ply_types.h"

namespace rephoto::splat {
namespace {

namespace fs = std::filesystem;

size_t ScalarSize(std::string_view type) {
  const std::optional<io::PlyType> parsed = io::ParsePlyType(type);
  return parsed ? static_cast<size_t>(io::PlyTypeSize(*parsed)) : 0;
}

std::vector<std::string> Words(const std::string& line) {
  std::istringstream in(line);
  std::vector<std::string> words;
  for (std::string word; in >> word;) words.push_back(word);
  return words;
}

}  // namespace

std::string WithVertexFloatProperty(std::string_view ply, std::string_view name,
                                    const std::vector<float>& values, std::string_view context) {
  const size_t end = ply.find("end_header\n");
  REPHOTO_CHECK(ply.starts_with("ply\n") && end != std::string_view::npos,
                "{}: not a PLY file with a header", context);
  const size_t body = end + std::strlen("end_header\n");
  std::vector<std::string> lines;
  {
    std::istringstream header{std::string(ply.substr(0, end))};
    for (std::string line; std::getline(header, line);) {
      if (!line.empty() && line.back() == '\r') line.pop_back();
      lines.push_back(line);
    }
  }
  size_t record = 0, count = 0, elements = 0, last_property = 0;
  std::optional<size_t> existing;  // byte offset of a float property `name` in a record
  bool little_endian = false;
  for (size_t i = 0; i < lines.size(); ++i) {
    const std::vector<std::string> w = Words(lines[i]);
    if (w.empty()) continue;
    if (w[0] == "format") little_endian = w.size() >= 2 && w[1] == "binary_little_endian";
    if (w[0] == "element") {
      ++elements;
      REPHOTO_CHECK(w.size() == 3 && w[1] == "vertex" && elements == 1,
                    "{}: PLY has elements besides 'vertex'", context);
      count = std::stoull(w[2]);
    }
    if (w[0] == "property") {
      REPHOTO_CHECK(w.size() == 3 && ScalarSize(w[1]) > 0,
                    "{}: PLY vertex property '{}' is not a scalar", context, lines[i]);
      if (w[2] == name) {
        REPHOTO_CHECK(w[1] == "float" || w[1] == "float32",
                      "{}: PLY has a property '{}' that is not float", context, name);
        existing = record;
      }
      record += ScalarSize(w[1]);
      last_property = i;
    }
  }
  REPHOTO_CHECK(little_endian, "{}: PLY is not binary_little_endian", context);
  REPHOTO_CHECK(count == values.size(), "{}: {} vertices but {} values", context, count,
                values.size());
  REPHOTO_CHECK(record > 0 && ply.size() - body >= count * record,
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
