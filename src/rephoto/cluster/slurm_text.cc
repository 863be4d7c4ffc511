#include "rephoto/cluster/slurm_text.h"

#include <fmt/format.h>
#include <xxhash.h>

#include <charconv>
#include <nlohmann/json.hpp>

#include "rephoto/core/error.h"

namespace rephoto::cluster {

namespace fs = std::filesystem;

namespace {

bool IsIdChar(char c) {
  return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' ||
         c == '.' || c == ':' || c == '+' || c == '-';
}

std::vector<std::string_view> SplitView(std::string_view text, char separator) {
  std::vector<std::string_view> parts;
  size_t start = 0;
  for (;;) {
    const size_t end = text.find(separator, start);
    if (end == std::string_view::npos) {
      parts.push_back(text.substr(start));
      return parts;
    }
    parts.push_back(text.substr(start, end - start));
    start = end + 1;
  }
}

std::string_view TrimView(std::string_view text) {
  const size_t begin = text.find_first_not_of(" \t\r\n");
  if (begin == std::string_view::npos) return {};
  const size_t end = text.find_last_not_of(" \t\r\n");
  return text.substr(begin, end - begin + 1);
}

std::optional<int> ParseInt(std::string_view text) {
  int value = 0;
  const char* end = text.data() + text.size();
  const auto [ptr, ec] = std::from_chars(text.data(), end, value);
  if (ec != std::errc() || ptr != end || text.empty()) return std::nullopt;
  return value;
}

bool IsDigits(std::string_view text) {
  return !text.empty() && text.find_first_not_of("0123456789") == std::string_view::npos;
}

// "123_4" -> ("123", 4); nullopt for "123", "123_[4-9]", "123_4.batch".
std::optional<std::pair<std::string, int>> SplitArrayTask(std::string_view job) {
  const size_t underscore = job.find('_');
  if (underscore == std::string_view::npos) return std::nullopt;
  const std::string_view array_job = job.substr(0, underscore);
  const std::optional<int> index = ParseInt(job.substr(underscore + 1));
  if (!IsDigits(array_job) || !index) return std::nullopt;
  return std::make_pair(std::string(array_job), *index);
}

// Escapes '%' for sbatch's file name patterns.
std::string EscapePercent(std::string_view text) {
  std::string out;
  for (char c : text) {
    out += c;
    if (c == '%') out += '%';
  }
  return out;
}

}  // namespace

void CheckTaskId(std::string_view id) {
  REPHOTO_CHECK_USAGE(!id.empty(), "task id '': empty");
  REPHOTO_CHECK_USAGE(id.size() <= 200, "task id '{}': longer than 200 characters", id);
  for (const std::string_view segment : SplitView(id, '/')) {
    REPHOTO_CHECK_USAGE(!segment.empty() && segment != "." && segment != "..",
                        "task id '{}': empty, '.' or '..' path segment", id);
    for (char c : segment) {
      REPHOTO_CHECK_USAGE(IsIdChar(c),
                          "task id '{}': character '{}' is not allowed (letters, digits and "
                          "_ . : + - in segments joined by /)",
                          id, c < 0x20 || c == 0x7f ? '?' : c);
    }
  }
}

void CheckGroupName(std::string_view name) {
  REPHOTO_CHECK_USAGE(!name.empty() && name.size() <= 64, "task group '{}': empty or too long",
                      name);
  for (char c : name) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_' || c == '-';
    REPHOTO_CHECK_USAGE(ok, "task group '{}': only a-z, 0-9, _ and - are allowed", name);
  }
}

std::string TaskFingerprint(const Task& task) {
  std::string serialized;
  for (const std::string& arg : task.argv) {
    serialized += fmt::format("{}:", arg.size());
    serialized += arg;
  }
  serialized += fmt::format("|key {}:", task.key.size());
  serialized += task.key;
  const XXH128_hash_t hash = XXH3_128bits(serialized.data(), serialized.size());
  return fmt::format("{:016x}{:016x}", hash.high64, hash.low64);
}

fs::path ResultPath(const fs::path& slurm_dir, std::string_view id) {
  return slurm_dir / "results" / (std::string(id) + ".json");
}

std::string MakeArrayScript(const ArraySpec& spec, const std::vector<std::string>& sbatch_argv) {
  std::string script = "#!/bin/sh\n";
  script += fmt::format(
      "# rephoto: task group '{}', submission {}, {} task(s); written by rephoto "
      "(src/rephoto/cluster/slurm.h).\n# Submitted as:\n#  ",
      spec.group, spec.submission, spec.tasks.size());
  for (const std::string& arg : sbatch_argv) {
    script += ' ';
    script += ShellQuote(arg);
  }
  script +=
      "\n# Array index i runs task i below. When its command exits, this script writes\n"
      "# results/<task id>.json atomically (exit code, node, times) and exits with the\n"
      "# command's exit code.\n";
  script += "index=\"${SLURM_ARRAY_TASK_ID:-}\"\ncase \"$index\" in\n";
  for (size_t i = 0; i < spec.tasks.size(); ++i) {
    const Task& task = *spec.tasks[i];
    script += fmt::format("  {})\n    id={}\n    fingerprint={}\n    set --", i, ShellQuote(task.id),
                          TaskFingerprint(task));
    for (const std::string& arg : task.argv) {
      script += ' ';
      script += ShellQuote(arg);
    }
    script += "\n    ;;\n";
  }
  script +=
      "  *)\n    echo \"rephoto: array index '$index' is not a task of this script\" >&2\n"
      "    exit 2\n    ;;\nesac\n";
  script += fmt::format("submission={}\nresults={}\n", spec.submission,
                        ShellQuote((spec.slurm_dir / "results").string()));
  // Three processes besides the command (two `date`, one `mv`): on a busy node every fork
  // counts, so names are checked with `case`, not `tr`, and the results folder exists already.
  script += R"SH(node="${SLURMD_NODENAME:-unknown}"
case "$node" in *[!A-Za-z0-9._-]*) node=unknown ;; esac
job="${SLURM_ARRAY_JOB_ID:-}"
case "$job" in *[!0-9]*) job= ;; esac
now=$(date -u '+%Y-%m-%dT%H:%M:%SZ %s')
start=${now% *}
start_seconds=${now#* }
echo "# rephoto task $id: array job $job index $index on $node at $start"
"$@"
code=$?
now=$(date -u '+%Y-%m-%dT%H:%M:%SZ %s')
end=${now% *}
seconds=$((${now#* } - start_seconds))
echo "# rephoto task $id: exit code $code at $end after $seconds s"
result="$results/$id.json"
if { [ -d "${result%/*}" ] || mkdir -p "${result%/*}"; } &&
  printf '{"schema":"rephoto.cluster.result/1","id":"%s","fingerprint":"%s","submission":%s,"job":"%s","index":%s,"node":"%s","exit_code":%s,"start":"%s","end":"%s","seconds":%s}\n' \
    "$id" "$fingerprint" "$submission" "$job" "$index" "$node" "$code" "$start" "$end" "$seconds" \
    >"$result.tmp-$$" &&
  mv -f "$result.tmp-$$" "$result"; then
  exit $code
fi
echo "# rephoto: cannot write the result file $result" >&2
rm -f "$result.tmp-$$"
[ $code -ne 0 ] && exit $code
exit 1
)SH";
  return script;
}

std::vector<std::string> SbatchArguments(const ArraySpec& spec, const fs::path& script) {
  REPHOTO_CHECK(!spec.tasks.empty() && spec.resources != nullptr,
                "SbatchArguments: an array needs tasks and resources");
  std::vector<std::string> args = {"--parsable", "--job-name=" + spec.job_name};
  std::string array = fmt::format("--array=0-{}", spec.tasks.size() - 1);
  if (spec.max_running > 0) array += fmt::format("%{}", spec.max_running);
  args.push_back(array);
  args.push_back("--output=" + EscapePercent(spec.slurm_dir.string()) + "/%A_%a.log");
  args.push_back("--open-mode=append");
  const SlurmResources& r = *spec.resources;
  if (!r.partition.empty()) args.push_back("--partition=" + r.partition);
  if (!r.time.empty()) args.push_back("--time=" + r.time);
  if (!r.mem.empty()) args.push_back("--mem=" + r.mem);
  if (!r.account.empty()) args.push_back("--account=" + r.account);
  if (!r.qos.empty()) args.push_back("--qos=" + r.qos);
  if (r.cpus_per_task > 0) args.push_back(fmt::format("--cpus-per-task={}", r.cpus_per_task));
  if (!spec.after_jobs.empty()) {
    std::string dependency = "--dependency=afterany";
    for (const std::string& job : spec.after_jobs) dependency += ":" + job;
    args.push_back(dependency);
  }
  args.insert(args.end(), r.options.begin(), r.options.end());
  args.push_back(script.string());
  return args;
}

std::string ParseSbatchJobId(std::string_view output) {
  std::string_view text = TrimView(output);
  // Some sites print warnings first; the id is on the last line.
  const size_t newline = text.find_last_of('\n');
  if (newline != std::string_view::npos) text = TrimView(text.substr(newline + 1));
  const std::string_view id = text.substr(0, text.find(';'));
  REPHOTO_CHECK(IsDigits(id), "sbatch: unexpected output '{}' (expected a job id)",
                TrimView(output).substr(0, 200));
  return std::string(id);
}

std::vector<QueueEntry> ParseSqueue(std::string_view output) {
  std::vector<QueueEntry> entries;
  for (const std::string_view line : SplitView(output, '\n')) {
    const std::vector<std::string_view> fields = SplitView(TrimView(line), '|');
    if (fields.size() < 5) continue;
    const std::optional<int> index = ParseInt(fields[1]);
    if (!IsDigits(fields[0]) || !index) continue;
    QueueEntry entry;
    entry.array_job = std::string(fields[0]);
    entry.index = *index;
    entry.state = std::string(fields[2]);
    entry.reason = std::string(fields[3]);
    entry.node = fields[4] == "(null)" ? "" : std::string(fields[4]);
    entries.push_back(std::move(entry));
  }
  return entries;
}

std::vector<QueueEntry> ParseSacct(std::string_view output) {
  std::vector<QueueEntry> entries;
  for (const std::string_view line : SplitView(output, '\n')) {
    const std::vector<std::string_view> fields = SplitView(TrimView(line), '|');
    if (fields.size() < 4) continue;
    const auto task = SplitArrayTask(fields[0]);
    if (!task) continue;
    QueueEntry entry;
    entry.array_job = task->first;
    entry.index = task->second;
    entry.state = std::string(fields[1].substr(0, fields[1].find(' ')));
    const std::vector<std::string_view> code = SplitView(fields[2], ':');
    if (code.size() == 2) {
      entry.exit_code = ParseInt(code[0]).value_or(-1);
      entry.signal = ParseInt(code[1]).value_or(0);
    }
    entry.node = fields[3] == "None assigned" ? "" : std::string(fields[3]);
    entries.push_back(std::move(entry));
  }
  return entries;
}

std::optional<std::string> FindJobOfScript(std::string_view output, std::string_view script) {
  for (const std::string_view line : SplitView(output, '\n')) {
    const size_t bar = line.find('|');
    if (bar == std::string_view::npos) continue;
    const std::string_view job = TrimView(line.substr(0, bar));
    std::string_view command = line.substr(bar + 1);
    if (!command.empty() && command.back() == '\r') command.remove_suffix(1);
    if (IsDigits(job) && command == script) return std::string(job);
  }
  return std::nullopt;
}

std::optional<int> ParseMaxArraySize(std::string_view output) {
  for (const std::string_view line : SplitView(output, '\n')) {
    const size_t equals = line.find('=');
    if (equals == std::string_view::npos) continue;
    if (TrimView(line.substr(0, equals)) != "MaxArraySize") continue;
    const std::optional<int> value = ParseInt(TrimView(line.substr(equals + 1)));
    if (value && *value > 0) return value;
    return std::nullopt;
  }
  return std::nullopt;
}

bool IsActiveState(std::string_view state) {
  for (const char* active :
       {"PENDING", "CONFIGURING", "RUNNING", "COMPLETING", "SUSPENDED", "REQUEUED", "REQUEUE_HOLD",
        "REQUEUE_FED", "RESIZING", "SIGNALING", "STAGE_OUT", "STOPPED"}) {
    if (state == active) return true;
  }
  return false;
}

bool IsStuckReason(std::string_view reason) {
  for (const char* stuck : {"JobHeld", "held", "DependencyNeverSatisfied", "BadConstraints",
                            "InvalidAccount", "InvalidQOS"}) {
    if (reason.find(stuck) != std::string_view::npos) return true;
  }
  return false;
}

std::string DescribeFinalState(std::string_view state) {
  if (state == "COMPLETED") return "completed";
  if (state == "FAILED") return "failed";
  if (state == "CANCELLED") return "cancelled";
  if (state == "TIMEOUT") return "timed out (--time)";
  if (state == "OUT_OF_MEMORY") return "ran out of memory (--mem)";
  if (state == "NODE_FAIL") return "its node failed";
  if (state == "BOOT_FAIL") return "its node failed to boot";
  if (state == "PREEMPTED") return "preempted";
  if (state == "DEADLINE") return "missed its deadline";
  std::string lower(state);
  for (char& c : lower) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return lower.empty() ? "ended" : lower;
}

std::optional<TaskResult> ParseTaskResult(std::string_view json) {
  const nlohmann::json doc = nlohmann::json::parse(json, nullptr, /*allow_exceptions=*/false);
  if (!doc.is_object() || doc.value("schema", "") != "rephoto.cluster.result/1")
    return std::nullopt;
  try {
    TaskResult result;
    result.id = doc.at("id").get<std::string>();
    result.fingerprint = doc.at("fingerprint").get<std::string>();
    result.submission = doc.at("submission").get<int>();
    result.job = doc.at("job").get<std::string>();
    result.index = doc.at("index").get<int>();
    result.node = doc.at("node").get<std::string>();
    result.exit_code = doc.at("exit_code").get<int>();
    result.start = doc.at("start").get<std::string>();
    result.end = doc.at("end").get<std::string>();
    result.seconds = doc.at("seconds").get<double>();
    return result;
  } catch (const nlohmann::json::exception&) {
    return std::nullopt;
  }
}

}  // namespace rephoto::cluster
