#include "rephoto/geometry/run_geometry.h"

#include <fmt/format.h>
#include <xxhash.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>

#include "rephoto/core/error.h"
#include "rephoto/core/file.h"
#include "rephoto/core/progress.h"
#include "rephoto/mesh/read_mesh.h"

namespace rephoto::geometry {
namespace fs = std::filesystem;
using Json = nlohmann::json;

namespace {

constexpr const char* kSchema = "rephoto.run_geometry/1";
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

Json ReadJson(const fs::path& path) {
  try {
    return Json::parse(ReadFileToString(path));
  } catch (const Json::exception& e) {
    throw Error(fmt::format("{}: not valid JSON: {}", path.string(), e.what()));
  }
}

// XXH3-64 of a file's content, as 16 hex digits.
std::string HashFile(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  REPHOTO_CHECK(in, "{}: cannot be read", path.string());
  XXH3_state_t* state = XXH3_createState();
  XXH3_64bits_reset(state);
  std::vector<char> buffer(1 << 20);
  while (in) {
    in.read(buffer.data(), static_cast<std::streamsize>(buffer.size()));
    XXH3_64bits_update(state, buffer.data(), static_cast<size_t>(in.gcount()));
  }
  const uint64_t digest = XXH3_64bits_digest(state);
  XXH3_freeState(state);
  REPHOTO_CHECK(in.eof(), "{}: read error", path.string());
  return fmt::format("{:016x}", digest);
}

std::string HashText(const std::string& text) {
  return fmt::format("{:016x}", XXH3_64bits(text.data(), text.size()));
}

// A fold's model path as written in fold.json: absolute, else relative to RUN, else as given.
fs::path ResolveModelPath(const fs::path& run_dir, const std::string& written) {
  const fs::path p = written;
  if (p.is_absolute()) return p;
  std::error_code ec;
  if (fs::exists(run_dir / p, ec)) return run_dir / p;
  return p;
}

double JsonNumber(const Json& j) { return j.is_number() ? j.get<double>() : kNaN; }
Json NumberJson(double v) { return std::isfinite(v) ? Json(v) : Json(); }

Json ToleranceJson(const ToleranceResult& t) {
  return {{"tolerance", t.tolerance},
          {"completeness", NumberJson(t.completeness)},
          {"precision", NumberJson(t.precision)},
          {"recall", NumberJson(t.recall)},
          {"f_score", NumberJson(t.f_score)}};
}

ToleranceResult ToleranceFromJson(const Json& j) {
  ToleranceResult t;
  t.tolerance = JsonNumber(j.value("tolerance", Json()));
  t.completeness = JsonNumber(j.value("completeness", Json()));
  t.precision = JsonNumber(j.value("precision", Json()));
  t.recall = JsonNumber(j.value("recall", Json()));
  t.f_score = JsonNumber(j.value("f_score", Json()));
  return t;
}

// The cache key's text: everything that changes the numbers.
std::string KeyText(const std::string& reference_hash, const std::vector<std::string>& model_hashes,
                    const GeometryOptions& o) {
  Json j = {{"schema", kSchema},
            {"reference", reference_hash},
            {"models", model_hashes},
            {"tolerances", o.tolerances},
            {"accuracy_fraction", o.accuracy_fraction},
            {"samples", o.samples},
            {"seed", o.seed}};
  std::vector<double> transform;
  for (int i = 0; i < 16; ++i) transform.push_back(o.model_from_input(i / 4, i % 4));
  j["transform"] = transform;
  if (o.crop) {
    j["crop"] = {(*o.crop)[0].x(), (*o.crop)[0].y(), (*o.crop)[0].z(),
                 (*o.crop)[1].x(), (*o.crop)[1].y(), (*o.crop)[1].z()};
  }
  return j.dump();
}

bool ReadCache(const fs::path& file, const GeometryOptions& options, RunGeometry* result) {
  std::error_code ec;
  if (!fs::is_regular_file(file, ec)) return false;
  try {
    const Json j = Json::parse(ReadFileToString(file));
    if (j.value("schema", "") != kSchema || !j.contains("tolerances") ||
        j["tolerances"].size() != options.tolerances.size()) {
      return false;
    }
    result->accuracy = JsonNumber(j.value("accuracy", Json()));
    result->accuracy_fraction = JsonNumber(j.value("accuracy_fraction", Json()));
    result->tolerances.clear();
    for (const Json& t : j["tolerances"]) result->tolerances.push_back(ToleranceFromJson(t));
    result->available = true;
    result->cached = true;
    return true;
  } catch (const std::exception& e) {
    LogWarning(fmt::format("{}: ignored ({})", file.string(), e.what()));
    return false;
  }
}

}  // namespace

std::vector<RunModel> FindRunModels(const fs::path& run_dir) {
  std::vector<RunModel> models;
  std::error_code ec;
  const fs::path folds = run_dir / "folds";
  if (fs::is_directory(folds, ec)) {
    std::vector<fs::path> dirs;
    for (const fs::directory_entry& e : fs::directory_iterator(folds, ec)) {
      if (e.is_directory(ec) && fs::is_regular_file(e.path() / "fold.json", ec)) {
        dirs.push_back(e.path());
      }
    }
    std::sort(dirs.begin(), dirs.end());
    // Derived models (coloured/degraded) by key: a fold whose model equals an earlier fold's
    // (same colorize_key) reuses it in memory and has no model.ply of its own.
    std::map<std::string, fs::path> derived_by_key;
    struct Pending {
      std::string fold, key;
      fs::path file;
    };
    std::vector<Pending> pending;
    for (const fs::path& dir : dirs) {
      const fs::path file = dir / "fold.json";
      const Json j = ReadJson(file);
      REPHOTO_CHECK(j.is_object(), "{}: expected a JSON object", file.string());
      if (j.value("status", "") != "ok") continue;
      const std::string fold = j.value("fold", dir.filename().string());
      const Json derived = j.value("colorized_model", Json());
      if (derived.is_string()) {
        // Inside the fold's folder only (the name comes from a file).
        const fs::path name = derived.get<std::string>();
        REPHOTO_CHECK(name.is_relative() && name.has_filename() && name == name.filename(),
                      "{}: colorized_model \"{}\" is not a file name", file.string(),
                      name.string());
        const std::string key = j.value("colorize_key", "");
        if (fs::is_regular_file(dir / name, ec)) {
          models.push_back({fold, dir / name});
          if (!key.empty()) derived_by_key.emplace(key, dir / name);
        } else {
          models.push_back({fold, fs::path()});
          pending.push_back({fold, key, file});
        }
        continue;
      }
      const Json model = j.value("model", Json());
      if (model.is_string() && !model.get<std::string>().empty()) {
        models.push_back({fold, ResolveModelPath(run_dir, model.get<std::string>())});
      }
    }
    for (const Pending& p : pending) {
      const auto it = derived_by_key.find(p.key);
      REPHOTO_CHECK(!p.key.empty() && it != derived_by_key.end(),
                    "{}: the fold's derived model (model.ply) is missing and no other fold has "
                    "the same colorize_key",
                    p.file.string());
      for (RunModel& m : models) {
        if (m.fold == p.fold && m.path.empty()) m.path = it->second;
      }
    }
    if (!dirs.empty()) return models;
  }
  const fs::path run_json = run_dir / "run.json";
  if (fs::is_regular_file(run_json, ec)) {
    const Json j = ReadJson(run_json);
    const Json path = j.is_object() ? j.value("/inputs/model/path"_json_pointer, Json()) : Json();
    if (path.is_string() && !path.get<std::string>().empty()) {
      models.push_back({"", ResolveModelPath(run_dir, path.get<std::string>())});
    }
  }
  return models;
}

RunGeometry EvaluateRunGeometry(const fs::path& run_dir, const fs::path& reference,
                                const GeometryOptions& options) {
  options.Check();
  RunGeometry result;
  result.accuracy = kNaN;
  result.accuracy_fraction = options.accuracy_fraction;
  try {
    result.models = FindRunModels(run_dir);
  } catch (const Error& e) {
    result.message = e.what();
    return result;
  }
  if (result.models.empty()) {
    result.message =
        fmt::format("{}: no model (a compare run, or rendered without a model)", run_dir.string());
    return result;
  }
  const std::string reference_hash = HashFile(reference);
  std::vector<std::string> model_hashes;
  for (const RunModel& m : result.models) {
    try {
      model_hashes.push_back(HashFile(m.path));
    } catch (const Error& e) {
      result.message = e.what();
      return result;
    }
  }
  const std::string key = HashText(KeyText(reference_hash, model_hashes, options));
  result.cache_file = run_dir / "geometry" / (key + ".json");
  if (ReadCache(result.cache_file, options, &result)) return result;

  // Each distinct model once; the numbers averaged over the folds.
  const mesh::Mesh gt = mesh::ReadMesh(reference);
  std::map<std::string, GeometryResult> by_hash;
  Json per_fold = Json::array();
  double accuracy_sum = 0;
  std::vector<ToleranceResult> sums(options.tolerances.size());
  for (size_t i = 0; i < result.models.size(); ++i) {
    const RunModel& m = result.models[i];
    auto it = by_hash.find(model_hashes[i]);
    if (it == by_hash.end()) {
      try {
        const mesh::Mesh model = mesh::ReadMesh(m.path);
        GeometryOptions o = options;
        o.vertex_distances = false;
        it = by_hash
                 .emplace(model_hashes[i],
                          EvaluateGeometry(model, gt, o, m.path.string(), reference.string()))
                 .first;
      } catch (const UsageError&) {
        throw;
      } catch (const Error& e) {
        result.message = e.what();
        return result;
      }
    }
    const GeometryResult& g = it->second;
    accuracy_sum += g.accuracy;
    Json tolerances = Json::array();
    for (size_t t = 0; t < sums.size(); ++t) {
      const ToleranceResult& r = g.tolerances[t];
      sums[t].tolerance = r.tolerance;
      sums[t].completeness += r.completeness;
      sums[t].precision += r.precision;
      sums[t].recall += r.recall;
      sums[t].f_score += r.f_score;
      tolerances.push_back(ToleranceJson(r));
    }
    per_fold.push_back({{"fold", m.fold},
                        {"model", m.path.string()},
                        {"model_hash", model_hashes[i]},
                        {"accuracy", NumberJson(g.accuracy)},
                        {"tolerances", tolerances},
                        {"model_samples", g.model_samples},
                        {"reference_samples", g.reference_samples},
                        {"seconds", g.seconds}});
  }
  const double n = static_cast<double>(result.models.size());
  result.accuracy = accuracy_sum / n;
  Json tolerances = Json::array();
  for (ToleranceResult& t : sums) {
    t.completeness /= n;
    t.precision /= n;
    t.recall /= n;
    t.f_score /= n;
    result.tolerances.push_back(t);
    tolerances.push_back(ToleranceJson(t));
  }
  result.available = true;

  const Json cache = {{"schema", kSchema},
                      {"reference", fs::absolute(reference).lexically_normal().string()},
                      {"reference_hash", reference_hash},
                      {"accuracy", NumberJson(result.accuracy)},
                      {"accuracy_fraction", options.accuracy_fraction},
                      {"tolerances", tolerances},
                      {"averaged_over_folds", result.models.size()},
                      {"folds", per_fold},
                      {"samples_requested", options.samples},
                      {"seed", options.seed},
                      {"key", KeyText(reference_hash, model_hashes, options)}};
  try {
    WriteTextFileAtomically(result.cache_file, cache.dump(2) + "\n");
  } catch (const Error& e) {
    LogWarning(fmt::format("geometry result not cached: {}", e.what()));
  }
  return result;
}

std::vector<std::string> RunGeometryColumns(const GeometryOptions& options) {
  std::vector<std::string> columns = {"geo_accuracy"};
  for (double t : options.tolerances) {
    for (const char* name : {"completeness", "precision", "recall", "f_score"}) {
      columns.push_back(fmt::format("geo_{}@{:g}", name, t));
    }
  }
  return columns;
}

std::vector<double> RunGeometryValues(const RunGeometry& result, const GeometryOptions& options) {
  std::vector<double> values;
  values.push_back(result.available ? result.accuracy : kNaN);
  for (size_t t = 0; t < options.tolerances.size(); ++t) {
    const bool ok = result.available && t < result.tolerances.size();
    const ToleranceResult r = ok ? result.tolerances[t] : ToleranceResult{};
    values.push_back(ok ? r.completeness : kNaN);
    values.push_back(ok ? r.precision : kNaN);
    values.push_back(ok ? r.recall : kNaN);
    values.push_back(ok ? r.f_score : kNaN);
  }
  return values;
}

}  // namespace rephoto::geometry
