#include "rephoto/cluster/slurm_settings.h"

#include <fmt/format.h>

#include <algorithm>
#include <charconv>
#include <regex>

#include "rephoto/core/error.h"

namespace rephoto::cluster {

namespace {

int ParseCount(std::string_view where, const std::string& value) {
  int count = 0;
  const auto [ptr, ec] = std::from_chars(value.data(), value.data() + value.size(), count);
  REPHOTO_CHECK_USAGE(ec == std::errc() && ptr == value.data() + value.size() && count >= 0,
                      "{}: '{}' is not a count (0, 1, 2, ...)", where, value);
  return count;
}

std::string CheckWord(std::string_view where, const std::string& value) {
  REPHOTO_CHECK_USAGE(!value.empty(), "{}: empty", where);
  for (const char c : value) {
    REPHOTO_CHECK_USAGE(static_cast<unsigned char>(c) > 0x20 && c != 0x7f,
                        "{}: '{}' holds a space or control character", where, value);
  }
  return value;
}

std::string CheckTime(std::string_view where, const std::string& value) {
  static const std::regex kTime(
      R"(\d+(:\d+){0,2}|\d+-\d+(:\d+){0,2}|INFINITE|UNLIMITED|infinite|unlimited)");
  REPHOTO_CHECK_USAGE(std::regex_match(value, kTime),
                      "{}: '{}' is not a Slurm time (minutes, h:mm:ss, days-hh:mm:ss)", where,
                      value);
  return value;
}

std::string CheckMemory(std::string_view where, const std::string& value) {
  static const std::regex kMemory(R"(\d+[KMGT]?)");
  REPHOTO_CHECK_USAGE(std::regex_match(value, kMemory),
                      "{}: '{}' is not a Slurm memory size (megabytes, or a number with K, M, G "
                      "or T)",
                      where, value);
  return value;
}

void SetResource(SlurmResources& resources, std::string_view key, const std::string& value,
                 std::string_view where) {
  if (key == "partition") {
    resources.partition = CheckWord(where, value);
  } else if (key == "time") {
    resources.time = CheckTime(where, value);
  } else if (key == "mem") {
    resources.mem = CheckMemory(where, value);
  } else if (key == "account") {
    resources.account = CheckWord(where, value);
  } else if (key == "qos") {
    resources.qos = CheckWord(where, value);
  } else if (key == "cpus-per-task") {
    resources.cpus_per_task = ParseCount(where, value);
  } else if (key == "option") {
    REPHOTO_CHECK_USAGE(!value.empty() && value[0] == '-',
                        "{}: '{}' is not an sbatch option (it must start with -)", where, value);
    resources.options.push_back(value);
  } else {
    throw UsageError(fmt::format("{}: unknown Slurm setting", where));
  }
}

}  // namespace

const std::vector<SlurmSettingInfo>& SlurmSettings() {
  static const std::vector<SlurmSettingInfo> settings = [] {
    std::vector<SlurmSettingInfo> list;
    const std::vector<std::pair<std::string, std::string>> resources = {
        {"partition", "Slurm partition (sbatch --partition)"},
        {"time", "time limit per task, in Slurm's syntax: minutes, h:mm:ss, days-hh:mm:ss"},
        {"mem", "memory per task (sbatch --mem), e.g. 4G"},
        {"account", "account charged (sbatch --account)"},
        {"qos", "quality of service (sbatch --qos)"},
        {"cpus-per-task", "CPUs per task (sbatch --cpus-per-task)"},
        {"option",
         "one more sbatch argument, passed verbatim, e.g. --constraint=avx2 "
         "(repeat for several)"}};
    for (const auto& [name, help] : resources) {
      list.push_back({name, "rephoto's own tasks: " + help, name == "option"});
    }
    for (const auto& [name, help] : resources) {
      list.push_back(
          {"reconstruct-" + name,
           "reconstruction commands: " + help +
               (name == "option" ? "; added to --slurm-option" : "; default: --slurm-" + name),
           name == "option"});
    }
    list.push_back(
        {"max-running", "at most this many tasks of one job array at once (0: no limit)", false});
    list.push_back({"poll", "seconds between two squeue calls while waiting", false});
    return list;
  }();
  return settings;
}

void SetSlurmSetting(SlurmOptions& options, std::string_view name, const std::string& value,
                     std::string_view where) {
  constexpr std::string_view kReconstruct = "reconstruct-";
  if (name.substr(0, kReconstruct.size()) == kReconstruct) {
    SetResource(options.reconstruct, name.substr(kReconstruct.size()), value, where);
  } else if (name == "max-running") {
    options.max_running = ParseCount(where, value);
  } else if (name == "poll") {
    double seconds = 0;
    const auto [ptr, ec] = std::from_chars(value.data(), value.data() + value.size(), seconds);
    REPHOTO_CHECK_USAGE(
        ec == std::errc() && ptr == value.data() + value.size() && seconds > 0 && seconds <= 3600,
        "{}: '{}' is not a number of seconds in (0, 3600]", where, value);
    options.poll_seconds = seconds;
  } else {
    SetResource(options.work, name, value, where);
  }
}

void ApplySlurmTable(SlurmOptions& options, const nlohmann::json& table, std::string_view file) {
  REPHOTO_CHECK_USAGE(table.is_object(), "{}: [slurm] is not a table", file);
  for (const auto& [key, value] : table.items()) {
    std::string name = key;
    for (char& c : name) c = c == '_' ? '-' : c;
    const std::string where = fmt::format("{}: [slurm] {}", file, key);
    const auto info = std::find_if(SlurmSettings().begin(), SlurmSettings().end(),
                                   [&](const SlurmSettingInfo& i) { return i.name == name; });
    REPHOTO_CHECK_USAGE(info != SlurmSettings().end(), "{}: unknown Slurm setting", where);
    const auto text = [&](const nlohmann::json& v) -> std::string {
      if (v.is_string()) return v.get<std::string>();
      if (v.is_number_integer()) return std::to_string(v.get<int64_t>());
      if (v.is_number()) return fmt::format("{}", v.get<double>());
      throw UsageError(fmt::format("{}: expected a string or a number, not {}", where, v.dump()));
    };
    if (value.is_array()) {
      REPHOTO_CHECK_USAGE(info->repeatable, "{}: expected one value, not a list", where);
      for (const nlohmann::json& element : value)
        SetSlurmSetting(options, name, text(element), where);
    } else {
      SetSlurmSetting(options, name, text(value), where);
    }
  }
}

SlurmOptions ResolveReconstructResources(SlurmOptions options) {
  SlurmResources& r = options.reconstruct;
  const SlurmResources& w = options.work;
  if (r.partition.empty()) r.partition = w.partition;
  if (r.time.empty()) r.time = w.time;
  if (r.mem.empty()) r.mem = w.mem;
  if (r.account.empty()) r.account = w.account;
  if (r.qos.empty()) r.qos = w.qos;
  if (r.cpus_per_task == 0) r.cpus_per_task = w.cpus_per_task;
  std::vector<std::string> merged = w.options;
  merged.insert(merged.end(), r.options.begin(), r.options.end());
  r.options = std::move(merged);
  return options;
}

}  // namespace rephoto::cluster
